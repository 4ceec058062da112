//! Corrupt, truncated and hostile files: every one is an error, never a panic.

mod common;

use amr_format::raw::{Footer, LAYOUT_VERSION};
use amr_format::{AmrkFile, FormatError};
use common::*;
use zerocopy::{FromBytes, IntoBytes};

/// Rewrites the footer and both checksums, so that structural checks, not checksums, must
/// catch the damage.
fn reseal(bytes: &mut [u8], mut footer: Footer) {
    let (start, len) = (
        footer.metadata.offset.get() as usize,
        footer.metadata.len.get() as usize,
    );
    if start.checked_add(len).is_some_and(|e| e <= bytes.len()) {
        footer.metadata_crc = crc32fast::hash(&bytes[start..start + len]).into();
    }
    let fb = footer.as_bytes();
    footer.footer_crc = crc32fast::hash(&fb[..fb.len() - 4]).into();
    let at = bytes.len() - size_of::<Footer>();
    bytes[at..].copy_from_slice(footer.as_bytes());
}

fn reseal_metadata(bytes: &mut [u8]) {
    let f = footer_of(bytes);
    reseal(bytes, f);
}

#[test]
fn empty_and_tiny_files() {
    assert!(open_err(Vec::new()).contains("truncated"));
    assert!(open_err(vec![0u8; 10]).contains("not an .amrk file"));
}

#[test]
fn wrong_magic() {
    let mut b = valid_file(1);
    b[0] ^= 0xFF;
    assert!(open_err(b).contains("not an .amrk file"));
}

#[test]
fn newer_layout_version() {
    let mut b = valid_file(2);
    let mut f = footer_of(&b);
    f.layout_version = (LAYOUT_VERSION + 1).into();
    reseal(&mut b, f);
    b[8..12].copy_from_slice(&(LAYOUT_VERSION + 1).to_le_bytes());
    let e = AmrkFile::open(b).err().unwrap();
    assert!(
        matches!(e, FormatError::Version { got, .. } if got == LAYOUT_VERSION + 1),
        "{e}"
    );
}

#[test]
fn truncated_anywhere() {
    let b = valid_file(3);
    for cut in [b.len() - 1, b.len() - 100, b.len() / 2, 300, 64] {
        let e = open_err(b[..cut].to_vec());
        assert!(
            e.contains("truncated") || e.contains("corrupt") || e.contains("checksum"),
            "cut {cut}: {e}"
        );
    }
}

#[test]
fn flipped_metadata_byte_fails_open() {
    let b = valid_file(4);
    let f = footer_of(&b);
    let start = f.metadata.offset.get() as usize;
    for off in [0, 17, 100, f.metadata.len.get() as usize - 1] {
        let mut c = b.clone();
        c[start + off] ^= 0x10;
        assert!(open_err(c).contains("checksum"), "offset {off}");
    }
}

#[test]
fn flipped_data_byte_fails_verify() {
    let mut b = valid_file(5);
    let at = AmrkFile::open(b.clone()).unwrap().brick_data(0, 0).offset as usize;
    b[at + 5] ^= 0x01;
    let file = AmrkFile::open(b).expect("data damage is found by verify, not open");
    let e = file.verify().err().unwrap().to_string();
    assert!(e.contains("checksum mismatch in field"), "{e}");
}

/// The block range tables lie outside the checksummed metadata (they are read in place): a
/// damaged entry is found by `verify`, which recomputes every table from the data.
#[test]
fn flipped_block_table_byte_fails_verify() {
    let mut b = valid_file(5);
    let f = footer_of(&b);
    let tables = f.block_tables.offset.get() - f.metadata.offset.get();
    let meta = &b[f.metadata.offset.get() as usize..];
    let first = u64::from_le_bytes(meta[tables as usize..][..8].try_into().unwrap());
    b[first as usize + 2] ^= 0x40;
    let file = AmrkFile::open(b).expect("table damage is found by verify, not open");
    let e = file.verify().err().unwrap().to_string();
    assert!(e.contains("block range table does not match"), "{e}");
}

/// Block tables of the wrong length, outside the data area, over brick data, or of blocks of
/// no cells are refused at open (checksums recomputed, so the structural checks must catch it).
#[test]
fn bad_block_tables_fail_open() {
    let b = valid_file(9);
    let f = footer_of(&b);
    let at = (f.block_tables.offset.get() - f.metadata.offset.get()) as usize;
    let meta_at = f.metadata.offset.get() as usize;
    let section = |bytes: &mut Vec<u8>, offset: u64, len: u64| {
        bytes[meta_at + at..][..8].copy_from_slice(&offset.to_le_bytes());
        bytes[meta_at + at + 8..][..8].copy_from_slice(&len.to_le_bytes());
        reseal_metadata(bytes);
    };
    let table = u64::from_le_bytes(b[meta_at + at..][..8].try_into().unwrap());
    let len = u64::from_le_bytes(b[meta_at + at + 8..][..8].try_into().unwrap());
    let data = AmrkFile::open(b.clone()).unwrap().brick_data(0, 0).offset;
    for (offset, len, want) in [
        (table, len - 8, "block table holds"),
        (table, len + 8, "block table holds"),
        (f.metadata.offset.get(), len, "outside the data area"),
        (u64::MAX - 4, len, "offset overflows"),
        (data, len, "overlaps brick data"),
    ] {
        let mut c = b.clone();
        section(&mut c, offset, len);
        let e = open_err(c);
        assert!(e.contains(want), "{offset}+{len}: {e}");
    }
    let mut c = b.clone();
    let mut g = footer_of(&c);
    g.block_cells = 0.into();
    reseal(&mut c, g);
    assert!(open_err(c).contains("block range tables of 0 cells"));
}

#[test]
fn offset_past_the_end() {
    let mut b = valid_file(6);
    let mut f = footer_of(&b);
    f.bricks.offset = (b.len() as u64 * 2).into();
    reseal(&mut b, f);
    assert!(open_err(b).contains("outside the metadata"));
}

#[test]
fn counts_that_would_overflow() {
    let b = valid_file(7);
    let mut c = b.clone();
    let mut f = footer_of(&c);
    f.num_bricks = u32::MAX.into();
    reseal(&mut c, f);
    assert!(open_err(c).contains("entries need"));
    let mut c = b.clone();
    let mut f = footer_of(&c);
    f.metadata.len = u64::MAX.into();
    reseal(&mut c, f);
    assert!(open_err(c).contains("overflows"));
}

#[test]
fn brick_data_offset_outside_field_region() {
    let mut b = valid_file(8);
    let f = footer_of(&b);
    let field: amr_format::raw::FieldRecord =
        amr_format::raw::FieldRecord::read_from_prefix(&b[f.fields.offset.get() as usize..])
            .unwrap()
            .0;
    let at = field.brick_data.offset.get() as usize;
    b[at..at + 8].copy_from_slice(&(u64::MAX - 3).to_le_bytes());
    reseal_metadata(&mut b);
    assert!(open_err(b).contains("outside the field's region"));
}

/// Seeded mutation fuzzing: flips, overwrites, truncations and extensions of valid files, half
/// of them resealed with fresh checksums so that structural validation is exercised. Every input
/// must open with an error or open, verify and be read entirely without a panic.
#[test]
fn seeded_mutations_never_panic() {
    let bases: Vec<Vec<u8>> = (10..14).map(valid_file).collect();
    let mut tried = 0u64;
    let mut opened = 0u64;
    for seed in 0..20_000u64 {
        let mut rng = Rng(seed);
        let mut b = bases[rng.below(bases.len() as u64) as usize].clone();
        let meta_start = footer_of(&b).metadata.offset.get() as usize;
        for _ in 0..1 + rng.below(4) {
            if b.is_empty() {
                break;
            }
            let meta_start = meta_start.min(b.len() - 1);
            match rng.below(5) {
                0 => {
                    let i = rng.below(b.len() as u64) as usize;
                    b[i] ^= 1 << rng.below(8);
                }
                1 => {
                    // Aim at the metadata, where structure lives.
                    let i = meta_start + rng.below((b.len() - meta_start) as u64) as usize;
                    b[i] = rng.next() as u8;
                }
                2 => {
                    let i = meta_start + rng.below((b.len() - meta_start) as u64) as usize;
                    let v =
                        [0u32, 1, u32::MAX, u32::MAX / 2, rng.next() as u32][rng.below(5) as usize];
                    let end = (i + 4).min(b.len());
                    b[i..end].copy_from_slice(&v.to_le_bytes()[..end - i]);
                }
                3 => {
                    let n = rng.below(b.len() as u64) as usize;
                    b.truncate(n);
                }
                _ => b.extend((0..rng.below(300)).map(|_| rng.next() as u8)),
            }
        }
        if rng.below(2) == 0 && b.len() >= 320 {
            reseal_metadata(&mut b);
        }
        tried += 1;
        let result = std::panic::catch_unwind(|| {
            if let Ok(file) = AmrkFile::open(b) {
                let _ = file.verify();
                for f in 0..file.fields().len() {
                    for i in 0..file.num_bricks() {
                        let _ = file.brick_values(f, i);
                    }
                    for l in 0..file.num_leaves() as u32 {
                        let _ = file.leaf_range(f, l);
                        let _ = file.leaf(l);
                    }
                }
                let _ = file.tree().find_leaf([0, 0, 0]);
                return true;
            }
            false
        });
        match result {
            Ok(true) => opened += 1,
            Ok(false) => {}
            Err(_) => panic!("seed {seed}: a mutated file made the reader panic"),
        }
    }
    eprintln!("mutation fuzzing: {tried} inputs tried, {opened} opened after mutation, no panic");
    assert_eq!(tried, 20_000);
}

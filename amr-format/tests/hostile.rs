//! Files whose checksums are right but whose structure is not: `open` refuses everything the
//! readers index by (issue 15), quickly, with one message naming the problem once.

mod common;

use std::time::{Duration, Instant};

use amr_format::raw::{Footer, Header, KdLeaf, KdNode, KD_LEAF};
use amr_format::reader::recompute_checksums;
use amr_format::{
    AmrkFile, AmrkWriter, BrickSpec, FormatError, HierarchySpec, IBox, LevelSpec, WriterOptions,
};
use common::*;
use zerocopy::{FromBytes, IntoBytes};

/// Stores `footer` and recomputes both checksums, so only structural checks can object.
fn reseal(bytes: &mut [u8], footer: Footer) {
    let at = bytes.len() - size_of::<Footer>();
    bytes[at..].copy_from_slice(footer.as_bytes());
    assert!(recompute_checksums(bytes));
}

fn nodes_of(b: &[u8]) -> (usize, Vec<KdNode>) {
    let f = footer_of(b);
    let at = f.nodes.offset.get() as usize;
    let n = f.num_nodes.get() as usize;
    let nodes = <[KdNode]>::ref_from_bytes(&b[at..at + 8 * n])
        .unwrap()
        .to_vec();
    (at, nodes)
}

/// The root's split plane moved by one cell: leaf boxes no longer match the tree (the renderer
/// indexed a brick at -1 with this file).
#[test]
fn moved_split_plane_is_refused() {
    let mut b = valid_file(21);
    let (at, nodes) = nodes_of(&b);
    assert_ne!(nodes[0].b.get() & 3, KD_LEAF, "the root must be a split");
    b[at..at + 4].copy_from_slice(&(nodes[0].a.get() + 1).to_le_bytes());
    let f = footer_of(&b);
    reseal(&mut b, f);
    let e = open_err(b);
    assert!(
        e.contains("but the tree gives it") || e.contains("not inside it"),
        "{e}"
    );
}

/// A brick-list entry naming a brick that does not cover the leaf (the renderer indexed past a
/// brick's values with this file).
#[test]
fn first_brick_not_covering_its_leaf_is_refused() {
    let mut b = valid_file(22);
    let f = footer_of(&b);
    let leaves = <[KdLeaf]>::ref_from_bytes(
        &b[f.leaves.offset.get() as usize..][..f.leaves.len.get() as usize],
    )
    .unwrap()
    .to_vec();
    let list_at = f.brick_list.offset.get() as usize;
    let entry =
        |b: &[u8], i: usize| u32::from_le_bytes(b[list_at + 4 * i..][..4].try_into().unwrap());
    let leaf = leaves.iter().find(|l| l.brick_count.get() > 0).unwrap();
    let i = leaf.brick_start.get() as usize;
    let first = entry(&b, i);
    let nb = f.num_bricks.get();
    // Some other brick: with a dozen or more bricks, most cannot cover this leaf.
    let file = AmrkFile::open(b.clone()).unwrap();
    let origin = file.finest_domain().lo;
    let lb = IBox::new(
        leaf.lo.map(|v| i64::from(v.get())),
        leaf.hi.map(|v| i64::from(v.get())),
    );
    let other = (0..nb)
        .find(|&k| {
            k != first
                && !file
                    .brick_finest_bounds(k as usize, origin)
                    .contains_box(&lb)
        })
        .unwrap();
    b[list_at + 4 * i..][..4].copy_from_slice(&other.to_le_bytes());
    let f = footer_of(&b);
    reseal(&mut b, f);
    let e = open_err(b);
    assert!(e.contains("does not cover it"), "{e}");
}

/// Every inner node's second child is the node after its first child's: a DAG whose walks take
/// Fibonacci(n) steps. Open refuses it at once.
#[test]
fn kd_tree_dag_is_refused_quickly() {
    let mut b = valid_file(23);
    let (at, nodes) = nodes_of(&b);
    let n = nodes.len();
    assert!(n > 40, "{n} nodes");
    for i in 0..n {
        let node = if i + 2 < n {
            KdNode {
                a: 1.into(),
                b: (((i as u32 + 2) << 2) | (i as u32 % 3)).into(),
            }
        } else {
            KdNode {
                a: ((i + 2 - n) as u32).into(),
                b: KD_LEAF.into(),
            }
        };
        b[at + 8 * i..][..8].copy_from_slice(node.as_bytes());
    }
    let f = footer_of(&b);
    reseal(&mut b, f);
    let start = Instant::now();
    let e = open_err(b);
    assert!(
        start.elapsed() < Duration::from_secs(1),
        "{:?}",
        start.elapsed()
    );
    assert!(
        e.contains("reached twice") || e.contains("not inside it") || e.contains("gives it"),
        "{e}"
    );
}

/// The same tree laid out out of depth-first order: a split whose first child splits into two
/// leaves and whose second child is a leaf, with the two last leaves' records swapped and the
/// second-child indices following them. Every node is still reached once with its region, but
/// the renderer's walks take a subtree to be the nodes from its root to the next sibling's, so
/// open refuses the layout.
#[test]
fn kd_nodes_out_of_depth_first_order_are_refused() {
    let leaf = |n: &KdNode| n.b.get() & 3 == KD_LEAF;
    let second = |n: &KdNode| (n.b.get() >> 2) as usize;
    let (mut b, at, nodes, p) = (0..8)
        .find_map(|seed| {
            let b = valid_file(30 + seed);
            let (at, nodes) = nodes_of(&b);
            let p = (0..nodes.len().saturating_sub(4)).find(|&p| {
                !leaf(&nodes[p])
                    && second(&nodes[p]) == p + 4
                    && leaf(&nodes[p + 4])
                    && !leaf(&nodes[p + 1])
                    && second(&nodes[p + 1]) == p + 3
                    && leaf(&nodes[p + 2])
                    && leaf(&nodes[p + 3])
            })?;
            Some((b, at, nodes, p))
        })
        .expect("a split over a split of two leaves and a leaf");
    let with_second = |n: &KdNode, s: usize| KdNode {
        a: n.a,
        b: (((s as u32) << 2) | (n.b.get() & 3)).into(),
    };
    let moved = [
        (p, with_second(&nodes[p], p + 3)),
        (p + 1, with_second(&nodes[p + 1], p + 4)),
        (p + 3, nodes[p + 4]),
        (p + 4, nodes[p + 3]),
    ];
    for (i, node) in moved {
        b[at + 8 * i..][..8].copy_from_slice(node.as_bytes());
    }
    let f = footer_of(&b);
    reseal(&mut b, f);
    let e = open_err(b);
    assert!(e.contains("not stored depth first"), "{e}");
}

#[test]
fn header_and_footer_sizes_are_checked() {
    let b = valid_file(24);
    let mut h = b.clone();
    let mut header = Header::read_from_prefix(&h).unwrap().0;
    header.header_size = 65.into();
    h[..64].copy_from_slice(header.as_bytes());
    assert!(open_err(h).contains("the header says it is 65 bytes"));
    let mut f = b.clone();
    let mut footer = footer_of(&f);
    footer.footer_size = 0.into();
    reseal(&mut f, footer);
    assert!(open_err(f).contains("the footer says it is 0 bytes"));
}

/// A message names its problem once: no cause is repeated through `source()`.
#[test]
fn messages_do_not_repeat_their_cause() {
    let mut b = valid_file(25);
    let mut footer = footer_of(&b);
    footer.footer_size = 0.into();
    reseal(&mut b, footer);
    let e = AmrkFile::open(b).err().unwrap().in_file("x.amrk");
    let mut chain = e.to_string();
    let mut src = std::error::Error::source(&e);
    while let Some(c) = src {
        chain = format!("{chain}: {c}");
        src = c.source();
    }
    assert_eq!(chain.matches("corrupt file").count(), 1, "{chain}");
    assert!(chain.starts_with("x.amrk: corrupt file: "), "{chain}");
    let io = FormatError::io("cannot open", std::io::Error::other("gone")).in_file("y");
    assert!(std::error::Error::source(&io).is_none());
    assert_eq!(io.to_string(), "y: cannot open: gone");
}

/// A legal file whose finest domain is 2^32 - 1 cells per axis verifies (the cell count
/// overflows u64).
#[test]
fn largest_domain_verifies() {
    let n = i64::from(u32::MAX);
    let spec = HierarchySpec {
        levels: vec![LevelSpec {
            cell_size: [1.0; 3],
            origin: [0.0; 3],
            ratio_to_next: [1; 3],
            domain: IBox::new([0; 3], [n; 3]),
        }],
        fields: vec!["f".into()],
        bricks: vec![BrickSpec {
            level: 0,
            cells: IBox::new([0; 3], [2; 3]),
        }],
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.amrk");
    let mut w = AmrkWriter::create(&path, spec, WriterOptions::default()).unwrap();
    w.write_brick(0, 0, &[1.0; 8]).unwrap();
    w.finish().unwrap();
    let file = AmrkFile::open(std::fs::read(&path).unwrap()).unwrap();
    let report = file.verify().unwrap();
    assert_eq!(report.covered_cells, (n as u128).pow(3));
}

//! What a path that is not an `.amrk` file looks like, so that the error can say what to do:
//! a simulation dump given to the renderer is converted first.

use std::io::Read;
use std::path::{Path, PathBuf};

/// The HDF5 signature, the first bytes of a Chombo or Enzo data file.
pub const HDF5_SIGNATURE: [u8; 8] = *b"\x89HDF\r\n\x1a\n";

/// Why `path` (not an `.amrk` file: a directory or wrong magic bytes) cannot be rendered, with
/// the conversion to run when it looks like a dump `amr-convert` reads.
pub fn not_amrk(path: &Path) -> String {
    let (kind, convert) = if path.is_dir() {
        let kind = match (
            path.join("Header").is_file(),
            has_file_ending(path, ".hierarchy"),
        ) {
            (true, _) => Some("an AMReX plotfile directory"),
            (false, true) => Some("an Enzo dataset directory"),
            (false, false) => None,
        };
        (kind, path.to_path_buf())
    } else if let Some(parameters) = enzo_parameter_file(path) {
        (Some("part of an Enzo dataset"), parameters)
    } else if first_bytes::<8>(path) == Some(HDF5_SIGNATURE) {
        (
            Some("an HDF5 file (a Chombo or AMReX HDF5 plotfile?)"),
            path.to_path_buf(),
        )
    } else if path.file_name().is_some_and(|n| n == "Header")
        && path.parent().is_some_and(|d| d.join("Level_0").is_dir())
    {
        let dir = path.parent().unwrap_or(path).to_path_buf();
        (Some("the Header of an AMReX plotfile"), dir)
    } else {
        (None, path.to_path_buf())
    };
    let what = match path.is_dir() {
        true => "a directory",
        false => "its first bytes are not an .amrk file's",
    };
    match kind {
        Some(kind) => format!(
            "not an .amrk file: this looks like {kind}; convert it first with `amr-convert {} -o OUT.amrk` (`amr-convert info {}` lists what it holds)",
            convert.display(),
            convert.display()
        ),
        None => format!("not an .amrk file ({what})"),
    }
}

/// The parameter file of the Enzo dataset `path` belongs to: `NAME` when `NAME.hierarchy` lies
/// beside it and `path` is `NAME`, `NAME.hierarchy`, `NAME.boundary` or a data file
/// `NAME.cpuNNNN`.
fn enzo_parameter_file(path: &Path) -> Option<PathBuf> {
    let name = path.to_string_lossy();
    let base = [".hierarchy", ".boundary", ".cpu"]
        .iter()
        .find_map(|s| name.rfind(s).map(|i| &name[..i]))
        .unwrap_or(&name);
    Path::new(&format!("{base}.hierarchy"))
        .is_file()
        .then(|| PathBuf::from(base))
}

/// The first `N` bytes of the file `path`, when it has that many (call it on a regular file
/// only: opening a FIFO waits for a writer).
pub fn first_bytes<const N: usize>(path: &Path) -> Option<[u8; N]> {
    let mut head = [0u8; N];
    std::fs::File::open(path).ok()?.read_exact(&mut head).ok()?;
    Some(head)
}

fn has_file_ending(dir: &Path, suffix: &str) -> bool {
    std::fs::read_dir(dir).is_ok_and(|entries| {
        entries
            .flatten()
            .take(10_000)
            .any(|e| e.file_name().to_string_lossy().ends_with(suffix))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dumps_are_told_apart_and_get_the_conversion() {
        let dir = tempfile::tempdir().unwrap();
        let plt = dir.path().join("plt00010");
        std::fs::create_dir_all(plt.join("Level_0")).unwrap();
        std::fs::write(plt.join("Header"), "HyperCLaw-V1.1\n").unwrap();
        let m = not_amrk(&plt);
        assert!(
            m.contains("AMReX plotfile directory") && m.contains("amr-convert"),
            "{m}"
        );
        let m = not_amrk(&plt.join("Header"));
        assert!(m.contains("Header of an AMReX plotfile"), "{m}");
        assert!(
            m.contains(&format!("amr-convert {} -o", plt.display())),
            "{m}"
        );
        let h5 = dir.path().join("chombo.hdf5");
        std::fs::write(&h5, [HDF5_SIGNATURE.as_slice(), &[0; 8]].concat()).unwrap();
        assert!(not_amrk(&h5).contains("HDF5"), "{}", not_amrk(&h5));
        let enzo = dir.path().join("DD0010");
        std::fs::create_dir(&enzo).unwrap();
        std::fs::write(enzo.join("data0010"), "InitialTime = 1\n").unwrap();
        std::fs::write(enzo.join("data0010.hierarchy"), "\n").unwrap();
        assert!(not_amrk(&enzo).contains("Enzo dataset directory"));
        std::fs::write(enzo.join("data0010.cpu0000"), HDF5_SIGNATURE.as_slice()).unwrap();
        for part in ["data0010", "data0010.hierarchy", "data0010.cpu0000"] {
            let m = not_amrk(&enzo.join(part));
            let want = format!("amr-convert {} -o", enzo.join("data0010").display());
            assert!(
                m.contains("part of an Enzo dataset") && m.contains(&want),
                "{m}"
            );
        }
        let other = dir.path().join("notes.txt");
        std::fs::write(&other, "hello").unwrap();
        assert_eq!(
            not_amrk(&other),
            "not an .amrk file (its first bytes are not an .amrk file's)"
        );
        let empty = dir.path().join("empty");
        std::fs::create_dir(&empty).unwrap();
        assert_eq!(not_amrk(&empty), "not an .amrk file (a directory)");
    }
}

//! Where each dump of a time series goes: several inputs (or an output ending in `/`) convert
//! into one directory, one `NAME.amrk` per dump, named after the dump (`plt00100` for an AMReX
//! plotfile directory, `chk0010` for `chk0010.3d.hdf5`, `DD0010` for an Enzo directory,
//! `moving7_0010` for its parameter file, `plt00100` for `plt00100.amrk`).

use amr_convert::derive::DerivedField;
use std::path::{Path, PathBuf};

use anyhow::bail;

/// Where each input of a conversion goes.
pub struct Outputs {
    /// Each input and the file it converts to.
    pub pairs: Vec<(PathBuf, PathBuf)>,
    /// The directory of a series when this call created it (so that a run that fails before
    /// writing into it can remove it again).
    pub created: Option<PathBuf>,
}

/// The `(input, output)` pairs of a conversion of `inputs` to `output`. For a series, every
/// input must exist before the output directory is made.
pub fn outputs(inputs: &[PathBuf], output: &Path) -> anyhow::Result<Outputs> {
    let to_dir = inputs.len() > 1 || output.as_os_str().to_string_lossy().ends_with('/');
    if !to_dir {
        let pairs = inputs
            .iter()
            .map(|i| (i.clone(), output.to_path_buf()))
            .collect();
        return Ok(Outputs {
            pairs,
            created: None,
        });
    }
    if output.exists() && !output.is_dir() {
        bail!(
            "{}: several inputs need a directory for their .amrk files, and this is a file",
            output.display()
        );
    }
    if let Some(missing) = inputs.iter().find(|i| !i.exists()) {
        bail!(
            "input {} does not exist (amr-convert tells the dump's format from its files: give \
             each dump's path, then -o)",
            missing.display()
        );
    }
    let created = (!output.exists()).then(|| output.to_path_buf());
    let mut pairs: Vec<(PathBuf, PathBuf)> = Vec::with_capacity(inputs.len());
    for input in inputs {
        let out = output.join(format!("{}.amrk", step_name(input)?));
        if let Some((other, _)) = pairs.iter().find(|(_, o)| *o == out) {
            bail!(
                "{} and {} would both be written to {}; convert them to different directories",
                other.display(),
                input.display(),
                out.display()
            );
        }
        pairs.push((input.clone(), out));
    }
    std::fs::create_dir_all(output)
        .map_err(|e| anyhow::anyhow!("{}: cannot create the directory: {e}", output.display()))?;
    Ok(Outputs { pairs, created })
}

/// Whether `output` is the conversion of dump `input` with the fields `fields` (or any, when
/// empty) followed by the fields `derived`, and newer than every file of the dump: a valid
/// `.amrk` file whose modification time is at or after theirs. Anything that cannot be read
/// counts as out of date. (A formula is not stored, so a derived field's new formula under its
/// old name is not noticed.)
pub fn up_to_date(
    input: &Path,
    output: &Path,
    fields: &[String],
    derived: &[DerivedField],
) -> bool {
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let (Some(written), Some(newest)) = (modified(output), newest_file_time(input)) else {
        return false;
    };
    if written < newest {
        return false;
    }
    let Ok(file) = amr_render::mapping::open_mapped(output) else {
        return false;
    };
    let mut asked: Vec<&str> = Vec::new();
    for f in fields {
        if !asked.contains(&f.as_str()) {
            asked.push(f);
        }
    }
    let has = |name: &str| file.fields().iter().any(|f| f.name == name);
    let derived: Vec<&str> = derived.iter().map(DerivedField::name).collect();
    if asked.is_empty() {
        return derived.iter().all(|d| has(d));
    }
    asked.extend(derived);
    file.fields().iter().map(|f| f.name.as_str()).eq(asked)
}

/// The latest modification time of the files of dump `input`: every file under a directory;
/// for a file, every file beside it whose name starts with its name (its own, or an Enzo
/// dataset's `NAME.hierarchy`, `NAME.cpu0000`, ... beside its parameter file `NAME`).
fn newest_file_time(input: &Path) -> Option<std::time::SystemTime> {
    fn newest_under(dir: &Path) -> Option<std::time::SystemTime> {
        let mut newest = std::fs::metadata(dir).ok()?.modified().ok()?;
        for entry in std::fs::read_dir(dir).ok()? {
            let path = entry.ok()?.path();
            let t = match path.is_dir() {
                true => newest_under(&path)?,
                false => std::fs::metadata(&path).ok()?.modified().ok()?,
            };
            newest = newest.max(t);
        }
        Some(newest)
    }
    if input.is_dir() {
        return newest_under(input);
    }
    let enzo = amr_convert::enzo::locate(input);
    let main = enzo.as_ref().map_or(input, |(params, _)| params.as_path());
    let name = main.file_name()?.to_string_lossy().into_owned();
    let dir = main.parent().filter(|d| !d.as_os_str().is_empty());
    let mut newest = std::fs::metadata(main).ok()?.modified().ok()?;
    for entry in std::fs::read_dir(dir.unwrap_or(Path::new("."))).ok()? {
        let entry = entry.ok()?;
        if entry.file_name().to_string_lossy().starts_with(&name) {
            newest = newest.max(entry.metadata().ok()?.modified().ok()?);
        }
    }
    Some(newest)
}

/// The name of a dump: its file or directory name without HDF5 extensions.
fn step_name(input: &Path) -> anyhow::Result<String> {
    // Any file of an Enzo dataset (`NAME.cpu0000`) is named after its parameter file.
    let enzo = input
        .is_file()
        .then(|| amr_convert::enzo::locate(input))
        .flatten();
    let input = enzo.as_ref().map_or(input, |(params, _)| params.as_path());
    let Some(name) = input.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        bail!("{}: no file name to name its .amrk after", input.display());
    };
    let mut stem = name.as_str();
    for ext in [".amrk", ".hdf5", ".h5", ".hierarchy", ".3d", ".2d"] {
        stem = stem.strip_suffix(ext).unwrap_or(stem);
    }
    Ok(stem.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_series_goes_to_a_directory_named_after_each_dump() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("series");
        let inputs = [
            PathBuf::from("run/plt00100"),
            PathBuf::from("run/chk0010.3d.hdf5"),
            PathBuf::from("run/old.amrk"),
        ];
        // The inputs must exist: a missing one is refused before the directory is made.
        assert!(outputs(&inputs, &out).is_err());
        assert!(!out.exists());
        let run = dir.path().join("run");
        let inputs = inputs.map(|i| dir.path().join(i));
        std::fs::create_dir_all(&inputs[0]).unwrap();
        assert!(outputs(&inputs, &out).is_err());
        assert!(!out.exists());
        std::fs::write(&inputs[1], b"").unwrap();
        std::fs::write(&inputs[2], b"").unwrap();
        let made = outputs(&inputs, &out).unwrap();
        assert_eq!(made.pairs[0].1, out.join("plt00100.amrk"));
        assert_eq!(made.pairs[1].1, out.join("chk0010.amrk"));
        // An .amrk file written anew keeps its name.
        assert_eq!(made.pairs[2].1, out.join("old.amrk"));
        assert_eq!(made.created.as_deref(), Some(out.as_path()));
        assert!(out.is_dir());
        assert_eq!(outputs(&inputs, &out).unwrap().created, None);
        let same = [run.join("plt1"), dir.path().join("plt1")];
        for s in &same {
            std::fs::create_dir_all(s).unwrap();
        }
        assert!(outputs(&same, &out).is_err());
        let single = outputs(&inputs[..1], Path::new("x.amrk")).unwrap();
        assert_eq!(single.pairs[0].1, PathBuf::from("x.amrk"));
    }

    #[test]
    fn an_enzo_data_file_names_its_step_after_the_parameter_file() {
        let dir = tempfile::tempdir().unwrap();
        for f in [
            "DD0010/data0010",
            "DD0010/data0010.hierarchy",
            "DD0010/data0010.cpu0000",
        ] {
            let p = dir.path().join(f);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, b"").unwrap();
        }
        let d = dir.path().join("DD0010");
        for input in ["data0010.cpu0000", "data0010.hierarchy", "data0010"] {
            assert_eq!(step_name(&d.join(input)).unwrap(), "data0010", "{input}");
        }
        assert_eq!(step_name(&d).unwrap(), "DD0010");
    }
}

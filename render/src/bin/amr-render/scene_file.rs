//! Scene files: everything a render command line says, as TOML, so that a figure or an animation
//! can be made again with `amr-render scene.toml`. The keys are the command's long options
//! (`size = "1024x768"`, `iso = ["10:orange", "5:#3070ff:0.4"]`, `orbit = 36`,
//! `no-shadows = true`) and `files` for the input files; the values are read by the same parsers
//! as the command line, so a scene file accepts exactly what the command line accepts. Options
//! given after the scene file on the command line take precedence. A relative path in a scene
//! file (an input, an output) is relative to the scene file's directory, so that a scene renders
//! the same from wherever it is run; `--write-scene` writes them so.

use std::any::TypeId;
use std::ffi::OsString;
use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::parser::ValueSource;
use clap::{Arg, ArgMatches, Command};
use toml::{Table, Value};

/// Key of the input files.
const FILES: &str = "files";

/// `argv` with a scene file in first position replaced by the arguments it holds, its relative
/// paths (the values of `cmd`'s path arguments) taken from the scene file's directory; the
/// arguments after it are kept, after those, so that they take precedence.
pub fn expand(argv: Vec<OsString>, cmd: &Command) -> anyhow::Result<Vec<OsString>> {
    let Some(first) = argv.get(1) else {
        return Ok(argv);
    };
    let path = Path::new(first);
    if path.extension().is_none_or(|e| e != "toml") {
        return Ok(argv);
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the scene file {}", path.display()))?;
    let table: Table = text
        .parse()
        .with_context(|| format!("{}: not a TOML scene file", path.display()))?;
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
    let from_scene = |key: &str, value: String| match (dir, is_path_key(cmd, key)) {
        (Some(dir), true) if value != "-" && Path::new(&value).is_relative() => {
            dir.join(value).into_os_string()
        }
        _ => OsString::from(value),
    };
    let mut out = vec![argv[0].clone()];
    out.extend(arguments(&table, &from_scene).with_context(|| format!("{}", path.display()))?);
    out.extend(argv[2..].iter().cloned());
    Ok(out)
}

/// The command-line arguments a scene file's table stands for, each value's text passed through
/// `text` with its key.
fn arguments(
    table: &Table,
    text: &dyn Fn(&str, String) -> OsString,
) -> anyhow::Result<Vec<OsString>> {
    let mut files = Vec::new();
    let mut options = Vec::new();
    for (key, value) in table {
        if key == FILES {
            match value {
                Value::Array(items) => {
                    for item in items {
                        files.push(text(key, scalar(key, item)?));
                    }
                }
                other => files.push(text(key, scalar(key, other)?)),
            }
            continue;
        }
        let flag = format!("--{}", key.replace('_', "-"));
        match value {
            Value::Boolean(true) => options.push(OsString::from(&flag)),
            Value::Boolean(false) => {}
            Value::Array(items) if items.iter().all(|v| v.is_integer() || v.is_float()) => {
                let parts: Vec<String> = items
                    .iter()
                    .map(|v| scalar(key, v))
                    .collect::<anyhow::Result<_>>()?;
                options.push(OsString::from(&flag));
                options.push(OsString::from(parts.join(",")));
            }
            Value::Array(items) => {
                for item in items {
                    options.push(OsString::from(&flag));
                    options.push(text(key, scalar(key, item)?));
                }
            }
            other => {
                options.push(OsString::from(&flag));
                options.push(text(key, scalar(key, other)?));
            }
        }
    }
    if files.is_empty() {
        bail!("no `files` (the .amrk files to render)");
    }
    files.extend(options);
    Ok(files)
}

/// Whether the scene file's `key` holds paths: `files`, or the long name of a path argument.
fn is_path_key(cmd: &Command, key: &str) -> bool {
    key == FILES
        || cmd
            .get_arguments()
            .any(|a| a.get_long() == Some(key) && takes_paths(a))
}

/// Whether `arg`'s values are paths.
fn takes_paths(arg: &Arg) -> bool {
    arg.get_value_parser().type_id() == TypeId::of::<PathBuf>()
}

/// `value`, a path as given on the command line, as seen from `dir`, the directory of the scene
/// file written: unchanged when absolute or `-` (standard output), else relative to `dir`. Both
/// are resolved through the file system where they exist (symbolic links and `..` as the system
/// follows them), so the relative path names the same file; else `value` is written absolute.
fn from_dir(value: &str, dir: &Path) -> anyhow::Result<String> {
    let path = Path::new(value);
    if value == "-" || path.is_absolute() {
        return Ok(value.to_owned());
    }
    let resolved = |p: &Path| std::fs::canonicalize(p).ok();
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    // An output need not exist yet: its directory does.
    let target = match (path.parent(), path.file_name()) {
        (Some(parent), Some(name)) => {
            let parent = if parent.as_os_str().is_empty() {
                Path::new(".")
            } else {
                parent
            };
            resolved(parent).map(|p| p.join(name))
        }
        _ => resolved(path),
    };
    let absolute = std::path::absolute(path)
        .with_context(|| format!("{value}: cannot make the path absolute"))?;
    let relative = match (target, resolved(dir)) {
        (Some(target), Some(base)) => pathdiff::diff_paths(&target, &base).unwrap_or(absolute),
        _ => absolute,
    };
    match relative.to_str() {
        Some("") => Ok(".".to_owned()),
        Some(s) => Ok(s.to_owned()),
        None => bail!(
            "{} is not valid UTF-8, which a TOML scene file cannot hold",
            relative.display()
        ),
    }
}

/// The text of a string or number.
fn scalar(key: &str, v: &Value) -> anyhow::Result<String> {
    match v {
        Value::String(s) => Ok(s.clone()),
        Value::Integer(i) => Ok(i.to_string()),
        Value::Float(f) => Ok(f.to_string()),
        other => bail!("`{key}`: {other} is not a string or a number"),
    }
}

/// A scene file checked and composed before the render, written once the render has succeeded:
/// a command that fails (a missing output directory, a field misspelt) leaves no scene behind,
/// nor replaces a scene file that worked with its own.
pub struct PendingScene {
    path: std::path::PathBuf,
    text: String,
}

impl PendingScene {
    /// Writes the scene file: beside its place, then renamed there, so never half-written.
    pub fn write(self) -> anyhow::Result<()> {
        let path = &self.path;
        let mut temp = amr_format::output::temporary_for(path, ".tmp")?;
        temp.write_all(self.text.as_bytes())
            .and_then(|()| temp.as_file().sync_all())
            .with_context(|| format!("cannot write {}", path.display()))?;
        temp.persist(path)
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(())
    }
}

/// The render arguments given in `matches` (parsed by `cmd`) as a scene file for `path`, checked
/// (the name, that it replaces no input, that every value can be written) but not yet written.
pub fn prepare(path: &Path, cmd: &Command, matches: &ArgMatches) -> anyhow::Result<PendingScene> {
    if path.extension().is_none_or(|e| e != "toml") {
        bail!(
            "{}: a scene file is named .toml (`amr-render SCENE.toml` renders it again)",
            path.display()
        );
    }
    // The data files must never be replaced by the scene that names them.
    let inputs: Vec<&Path> = matches
        .get_raw(FILES)
        .into_iter()
        .flatten()
        .map(Path::new)
        .collect();
    amr_format::output::check_output(path, &inputs)?;
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut table = Table::new();
    for arg in cmd.get_arguments() {
        let id = arg.get_id().as_str();
        if id == "write_scene" || matches.value_source(id) != Some(ValueSource::CommandLine) {
            continue;
        }
        let paths_from = takes_paths(arg).then_some(dir);
        let Some(long) = arg.get_long() else {
            if id == FILES {
                let files = raw_values(matches, id, paths_from)?;
                table.insert(FILES.into(), Value::Array(files));
            }
            continue;
        };
        let value = if !arg.get_action().takes_values() {
            Value::Boolean(true)
        } else {
            let mut values = raw_values(matches, id, paths_from)?;
            match arg.get_num_args().is_some_and(|n| n.max_values() > 1)
                || matches!(arg.get_action(), clap::ArgAction::Append)
            {
                true => Value::Array(values),
                false => values.pop().unwrap_or(Value::Boolean(true)),
            }
        };
        table.insert(long.into(), value);
    }
    let text = toml::to_string_pretty(&table)?;
    let header = "# amr-render scene file: `amr-render THIS.toml` renders it again.\n";
    Ok(PendingScene {
        path: path.to_owned(),
        text: format!("{header}{text}"),
    })
}

/// The values of `id` as given, numbers as numbers, paths (with `paths_from`, the scene file's
/// directory) as seen from there; an error for a value that is not UTF-8 (a path TOML cannot
/// hold: written with replacement characters, it would name another file).
fn raw_values(
    matches: &ArgMatches,
    id: &str,
    paths_from: Option<&Path>,
) -> anyhow::Result<Vec<Value>> {
    matches
        .get_raw(id)
        .into_iter()
        .flatten()
        .map(|raw| {
            let Some(s) = raw.to_str() else {
                bail!(
                    "{} is not valid UTF-8, which a TOML scene file cannot hold; rename it",
                    raw.to_string_lossy()
                );
            };
            if let Some(dir) = paths_from {
                return Ok(Value::String(from_dir(s, dir)?));
            }
            Ok(match s.parse::<i64>() {
                Ok(i) => Value::Integer(i),
                Err(_) => match s.parse::<f64>() {
                    Ok(f) if f.is_finite() && !s.contains(['x', 'X']) => Value::Float(f),
                    _ => Value::String(s.to_owned()),
                },
            })
        })
        .collect()
}

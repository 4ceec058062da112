//! Typed reads of attributes and datasets of one HDF5 group, with errors that name the file,
//! the group and the attribute, and that say what was expected.

use std::path::Path;

use hdf5_metno::types::{FixedAscii, FixedUnicode, TypeDescriptor, VarLenAscii, VarLenUnicode};
use hdf5_metno::{Attribute, Dataset, Group, H5Type};

use super::error::{ChomboError, Result};

/// The name [`Props`] gives the file's root group in messages.
pub(crate) const ROOT: &str = "root";

/// Longest string attribute read (component names are short).
const MAX_STRING: usize = 1024;

/// One group of the file, with its attribute names read once.
pub(crate) struct Props<'a> {
    path: &'a Path,
    group: Group,
    /// Where the group is, for messages: `root`, `level_2`, `level_2/data_attributes`.
    name: String,
    attrs: Vec<String>,
}

impl<'a> Props<'a> {
    /// Wraps `group`, called `name` in messages.
    pub fn new(path: &'a Path, group: Group, name: impl Into<String>) -> Result<Self> {
        let name = name.into();
        let attrs = group
            .attr_names()
            .map_err(|e| ChomboError::hdf5(path, format!("listing the attributes of {name}"), e))?;
        Ok(Self {
            path,
            group,
            name,
            attrs,
        })
    }

    /// The group's name as used in messages.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// True when the group has the attribute `attr`.
    pub fn has(&self, attr: &str) -> bool {
        self.attrs.iter().any(|a| a == attr)
    }

    /// True when the group has a member (group or dataset) called `name`.
    pub fn has_member(&self, name: &str) -> bool {
        self.group.link_exists(name)
    }

    /// The names of the group's members.
    pub fn member_names(&self) -> Result<Vec<String>> {
        self.group
            .member_names()
            .map_err(|e| self.hdf5(format!("listing the members of {}", self.name), e))
    }

    /// An error saying something about this group is wrong.
    pub fn invalid(&self, msg: impl std::fmt::Display) -> ChomboError {
        ChomboError::invalid(self.path, format!("{}: {msg}", self.name))
    }

    /// An error saying this group uses something the converter does not support.
    pub fn unsupported(&self, msg: impl std::fmt::Display) -> ChomboError {
        ChomboError::unsupported(self.path, format!("{}: {msg}", self.name))
    }

    /// Wraps an HDF5 library error.
    pub fn hdf5(&self, what: impl Into<String>, e: hdf5_metno::Error) -> ChomboError {
        ChomboError::hdf5(self.path, what, e)
    }

    /// The child group `name`, which must exist.
    pub fn child(&self, name: &str) -> Result<Props<'a>> {
        if !self.has_member(name) {
            return Err(self.invalid(format!("missing group '{name}'")));
        }
        let full = if self.name == ROOT {
            name.to_string()
        } else {
            format!("{}/{name}", self.name)
        };
        let g = self
            .group
            .group(name)
            .map_err(|e| self.hdf5(format!("opening group {full}"), e))?;
        Props::new(self.path, g, full)
    }

    /// The dataset `name`, which must exist.
    pub fn dataset(&self, name: &str) -> Result<Dataset> {
        if !self.has_member(name) {
            return Err(self.invalid(format!("missing dataset '{name}'")));
        }
        self.group
            .dataset(name)
            .map_err(|e| self.hdf5(format!("opening dataset {}/{name}", self.name), e))
    }

    fn attr(&self, attr: &str) -> Result<(Attribute, TypeDescriptor)> {
        if !self.has(attr) {
            return Err(self.invalid(format!("missing attribute '{attr}'")));
        }
        let what = || format!("reading attribute {}:{attr}", self.name);
        let a = self.group.attr(attr).map_err(|e| self.hdf5(what(), e))?;
        let d = a
            .dtype()
            .and_then(|t| t.to_descriptor())
            .map_err(|e| self.hdf5(what(), e))?;
        Ok((a, d))
    }

    /// The type of attribute `attr`.
    pub fn descriptor(&self, attr: &str) -> Result<TypeDescriptor> {
        self.attr(attr).map(|(_, d)| d)
    }

    /// Reads the single value of `attr` as `T` (a scalar, or an array of one element).
    fn one<T: H5Type>(&self, attr: &str, a: &Attribute) -> Result<T> {
        self.check_count(attr, a, 1)?;
        let v = a
            .read_raw::<T>()
            .map_err(|e| self.hdf5(format!("reading attribute {}:{attr}", self.name), e))?;
        v.into_iter()
            .next()
            .ok_or_else(|| self.invalid(format!("attribute '{attr}' holds no value")))
    }

    /// An integer attribute.
    pub fn int(&self, attr: &str) -> Result<i64> {
        let (a, d) = self.attr(attr)?;
        if !matches!(d, TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_)) {
            return Err(self.invalid(format!(
                "attribute '{attr}' has type {d}, expected an integer"
            )));
        }
        self.one::<i64>(attr, &a)
    }

    /// A floating-point attribute.
    pub fn float(&self, attr: &str) -> Result<f64> {
        let (a, d) = self.attr(attr)?;
        if !matches!(d, TypeDescriptor::Float(_)) {
            return Err(self.invalid(format!(
                "attribute '{attr}' has type {d}, expected a real number"
            )));
        }
        self.one::<f64>(attr, &a)
    }

    /// An error unless attribute `attr` (`a`) holds `n` values, checked before it is read: a
    /// damaged dataspace may declare billions.
    fn check_count(&self, attr: &str, a: &Attribute, n: usize) -> Result<()> {
        match a.size() {
            m if m == n => Ok(()),
            m => Err(self.invalid(format!("attribute '{attr}' holds {m} values, expected {n}"))),
        }
    }

    /// A floating-point attribute of exactly `N` values (AMReX's `Vec_dx`, `prob_lo`).
    pub fn floats<const N: usize>(&self, attr: &str) -> Result<[f64; N]> {
        let real = |d: &TypeDescriptor| matches!(d, TypeDescriptor::Float(_));
        self.array(attr, real, "real numbers")
    }

    /// An integer attribute of exactly `N` values (AMReX's `domain_type`).
    pub fn ints<const N: usize>(&self, attr: &str) -> Result<[i64; N]> {
        let int = |d: &TypeDescriptor| {
            matches!(d, TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_))
        };
        self.array(attr, int, "integers")
    }

    /// Attribute `attr` as `N` values of `T`, its stored type accepted by `stored` (else an error
    /// expecting `what`).
    fn array<T: H5Type, const N: usize>(
        &self,
        attr: &str,
        stored: impl Fn(&TypeDescriptor) -> bool,
        what: &str,
    ) -> Result<[T; N]> {
        let (a, d) = self.attr(attr)?;
        if !stored(&d) {
            return Err(self.invalid(format!("attribute '{attr}' has type {d}, expected {what}")));
        }
        self.check_count(attr, &a, N)?;
        let v = a
            .read_raw::<T>()
            .map_err(|e| self.hdf5(format!("reading attribute {}:{attr}", self.name), e))?;
        let n = v.len();
        v.try_into()
            .map_err(|_| self.invalid(format!("attribute '{attr}' holds {n} values, expected {N}")))
    }

    /// A string attribute (fixed or variable length, ASCII or UTF-8), trailing NULs removed.
    /// Bytes that are not UTF-8 are an error (the HDF5 types' `as_str` does not check them).
    pub fn string(&self, attr: &str) -> Result<String> {
        let (a, d) = self.attr(attr)?;
        let bytes = match d {
            TypeDescriptor::FixedAscii(n) if n <= MAX_STRING => self
                .one::<FixedAscii<MAX_STRING>>(attr, &a)?
                .as_bytes()
                .to_vec(),
            TypeDescriptor::FixedUnicode(n) if n <= MAX_STRING => self
                .one::<FixedUnicode<MAX_STRING>>(attr, &a)?
                .as_bytes()
                .to_vec(),
            TypeDescriptor::VarLenAscii => self.one::<VarLenAscii>(attr, &a)?.as_bytes().to_vec(),
            TypeDescriptor::VarLenUnicode => {
                self.one::<VarLenUnicode>(attr, &a)?.as_bytes().to_vec()
            }
            d => {
                return Err(self.invalid(format!(
                "attribute '{attr}' has type {d}, expected a string of at most {MAX_STRING} bytes"
            )))
            }
        };
        let s = String::from_utf8(bytes).map_err(|e| {
            self.invalid(format!(
                "attribute '{attr}' is not UTF-8 text (invalid byte at {})",
                e.utf8_error().valid_up_to()
            ))
        })?;
        Ok(s.trim_end_matches('\0').to_string())
    }

    /// A compound attribute read member by member into `T`; `members` must all be present.
    pub fn compound<T: H5Type>(&self, attr: &str, members: &[&str]) -> Result<T> {
        let (a, d) = self.attr(attr)?;
        check_members(&d, members).map_err(|m| self.invalid(format!("attribute '{attr}': {m}")))?;
        self.one::<T>(attr, &a)
    }
}

/// Checks that `desc` is a compound with every member of `members`, each a number.
pub(crate) fn check_members(
    desc: &TypeDescriptor,
    members: &[&str],
) -> std::result::Result<(), String> {
    let TypeDescriptor::Compound(c) = desc else {
        return Err(format!(
            "type {desc}, expected a compound with members {}",
            members.join(", ")
        ));
    };
    for m in members {
        match c.fields.iter().find(|f| f.name == *m) {
            None => {
                return Err(format!(
                    "compound has no member '{m}' (expected {})",
                    members.join(", ")
                ))
            }
            Some(f) => {
                if !matches!(
                    f.ty,
                    TypeDescriptor::Integer(_)
                        | TypeDescriptor::Unsigned(_)
                        | TypeDescriptor::Float(_)
                ) {
                    return Err(format!("member '{m}' has type {}, expected a number", f.ty));
                }
            }
        }
    }
    Ok(())
}

//! Derived fields: a new field computed cell by cell from a formula over stored fields
//! (`speed=|x-velocity,y-velocity,z-velocity|`, `temperature=pressure/density`), written into
//! the `.amrk` file like any other field so that it can be contoured, painted and bounded.

use std::fmt;
use std::str::FromStr;

use crate::differential::Operator;
use amr_render::coloring::ColorBy;
use exmex::prelude::*;
use exmex::{literal_matcher_from_pattern, FloatOpsFactory, MatchLiteral};

// Numbers as scientists write them, `1e-30` and `6.67E-8` included (exmex's own matcher takes
// no exponent).
literal_matcher_from_pattern!(
    ScientificNumber,
    r"^(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][+-]?[0-9]+)?"
);

/// A parsed formula over `f64`.
type Formula = FlatEx<f64, FloatOpsFactory<f64>, ScientificNumber>;

/// How a derived field is written on the command line, for messages.
pub const EXAMPLES: &str =
    "speed='|x-velocity,y-velocity,z-velocity|' or temperature='pressure/density'";

/// A field to compute from others: its name and its formula, parsed.
#[derive(Clone, Debug)]
pub struct DerivedField {
    name: String,
    formula: String,
    computation: Computation,
}

/// How a derived field's values are computed.
#[derive(Clone, Debug)]
enum Computation {
    /// The length of the vector of these fields' values, computed directly: the common case,
    /// at the cost of copying a field (as an expression, its `^2` calls `pow` and the
    /// interpreter costs tens of nanoseconds a cell: `docs/benchmarks-convert.md`).
    Magnitude(Vec<String>),
    /// An operator on the fields' gradients at each cell, `grad(f)`, `curl(u,v,w)`,
    /// `div(u,v,w)` or `qcriterion(u,v,w)` ([`crate::differential`]).
    Differential(Operator, Vec<String>),
    /// Any other formula, interpreted (boxed: the parsed form is large).
    Expression(Box<Formula>),
}

/// Why a derived field cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DeriveError {
    /// The argument is not `NAME=FORMULA`.
    #[error("--derive '{given}': expected NAME=FORMULA, as {EXAMPLES}")]
    Syntax {
        /// The argument as given.
        given: String,
    },
    /// The formula does not parse.
    #[error("--derive {name}: cannot read the formula '{formula}': {reason}")]
    Formula {
        /// The derived field's name.
        name: String,
        /// The formula as given.
        formula: String,
        /// The parser's explanation.
        reason: String,
    },
    /// The formula reads no field.
    #[error("--derive {name}: the formula '{formula}' reads no field")]
    Constant {
        /// The derived field's name.
        name: String,
        /// The formula as given.
        formula: String,
    },
    /// The formula reads a field the input does not have.
    #[error("--derive {name}: the input has no field named '{field}'{hint}; it has: {available}")]
    UnknownField {
        /// The derived field's name.
        name: String,
        /// The missing field.
        field: String,
        /// A field differing only in letter case, or a reminder that names with other
        /// characters than letters, digits and `_` go in braces.
        hint: String,
        /// The input's fields, comma-separated.
        available: String,
    },
    /// An operator on gradients reads a field derived in the same run.
    #[error(
        "--derive {name}: '{field}' is derived in this run, and an operator on gradients reads \
         stored fields only (their neighbours): write the file with '{field}' first, then \
         derive {name} from it"
    )]
    NotStored {
        /// The derived field's name.
        name: String,
        /// The field derived before it.
        field: String,
    },
    /// The derived field's name is taken.
    #[error("--derive {name}: {why}; give the derived field another name")]
    NameTaken {
        /// The derived field's name.
        name: String,
        /// What has the name already.
        why: String,
    },
}

impl FromStr for DerivedField {
    type Err = DeriveError;

    /// Parses `NAME=FORMULA`. The formula is a magnitude `|a,b,c|` (the length of the vector
    /// of those fields, as `--color-by` writes it) or an expression of fields, numbers, `+ - *
    /// / ^`, and functions such as `sqrt`, `abs`, `ln`, `log10`, `exp`, `min` and `max`; a field
    /// named with characters other than letters, digits and `_` is written in braces,
    /// `{x-velocity}`.
    fn from_str(given: &str) -> Result<Self, DeriveError> {
        let syntax = || DeriveError::Syntax {
            given: given.to_string(),
        };
        let (name, formula) = given.split_once('=').ok_or_else(syntax)?;
        let (name, formula) = (name.trim(), formula.trim());
        if name.is_empty() || formula.is_empty() {
            return Err(syntax());
        }
        let bad = |reason: String| DeriveError::Formula {
            name: name.to_string(),
            formula: formula.to_string(),
            reason,
        };
        let computation = match (formula.starts_with('|'), differential(formula)) {
            (true, _) => Computation::Magnitude(magnitude_fields(formula).map_err(bad)?),
            (false, Some((op, fields))) => {
                if fields.len() != op.arity() || fields.iter().any(|f| f.is_empty()) {
                    return Err(bad(match op.arity() {
                        1 => format!("{op} takes one field, as {op}(density)"),
                        _ => format!(
                            "{op} takes a vector's three fields, x first, as \
                             {op}(x-velocity,y-velocity,z-velocity)"
                        ),
                    }));
                }
                Computation::Differential(op, fields)
            }
            (false, None) if calls_an_operator(formula) => {
                return Err(bad(format!(
                    "{} stand alone as a whole formula: derive the operator under a name of its \
                     own",
                    OPERATORS.join(", ")
                )));
            }
            (false, None) => {
                let expr = Formula::parse(formula).map_err(|e| bad(e.to_string()))?;
                if expr.var_names().is_empty() {
                    return Err(DeriveError::Constant {
                        name: name.to_string(),
                        formula: formula.to_string(),
                    });
                }
                Computation::Expression(Box::new(expr))
            }
        };
        Ok(DerivedField {
            name: name.to_string(),
            formula: formula.to_string(),
            computation,
        })
    }
}

/// The operators on gradients, as formulas write them.
const OPERATORS: [&str; 4] = ["grad", "curl", "div", "qcriterion"];

/// Whether `text` calls an operator on gradients.
fn calls_an_operator(text: &str) -> bool {
    OPERATORS.iter().any(|o| text.contains(&format!("{o}(")))
}

/// The operator and its fields when `formula` is one call `op(a,b,c)` of a differential
/// operator (a field name may be in braces).
fn differential(formula: &str) -> Option<(Operator, Vec<String>)> {
    let (name, rest) = formula.split_once('(')?;
    let op = Operator::named(name.trim())?;
    let inner = rest.trim_end().strip_suffix(')')?;
    if calls_an_operator(inner) {
        return None;
    }
    let fields = inner
        .split(',')
        .map(|f| {
            let f = f.trim();
            f.strip_prefix('{')
                .and_then(|f| f.strip_suffix('}'))
                .unwrap_or(f)
                .to_string()
        })
        .collect();
    Some((op, fields))
}

/// The fields of the magnitude `|a,b,c|`.
fn magnitude_fields(formula: &str) -> Result<Vec<String>, String> {
    match formula.parse::<ColorBy>() {
        Ok(ColorBy::Magnitude { fields, .. }) => Ok(fields),
        _ => Err(
            "a magnitude names two or more fields between bars, as '|x-velocity,y-velocity|'"
                .into(),
        ),
    }
}

impl DerivedField {
    /// The derived field's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The formula as given.
    pub fn formula(&self) -> &str {
        &self.formula
    }

    /// The fields the formula reads, in the order [`evaluate`](Self::evaluate) takes their
    /// values.
    pub fn inputs(&self) -> &[String] {
        match &self.computation {
            Computation::Magnitude(fields) | Computation::Differential(_, fields) => fields,
            Computation::Expression(expr) => expr.var_names(),
        }
    }

    /// The position in `fields` of each field the formula reads, or which one is missing.
    pub fn bind(&self, fields: &[String]) -> Result<Vec<usize>, DeriveError> {
        self.inputs()
            .iter()
            .map(|input| {
                fields
                    .iter()
                    .position(|f| f == input)
                    .ok_or_else(|| self.unknown(input, fields))
            })
            .collect()
    }

    /// Refuses the derived field's name when `taken` (the input's fields, or the output's
    /// other fields) holds it.
    pub fn check_name(&self, taken: &[String]) -> Result<(), DeriveError> {
        match taken.contains(&self.name) {
            true => Err(DeriveError::NameTaken {
                name: self.name.clone(),
                why: "a field of that name exists already".into(),
            }),
            false => Ok(()),
        }
    }

    fn unknown(&self, input: &str, fields: &[String]) -> DeriveError {
        let mut hint = amr_render::error::same_but_case(input, fields);
        if hint.is_empty() && fields.iter().any(|f| f.contains(input) && f != input) {
            hint = " (a field named with characters other than letters, digits and _ is \
                    written in braces: {x-velocity})"
                .into();
        }
        DeriveError::UnknownField {
            name: self.name.clone(),
            field: input.to_string(),
            hint,
            available: fields.join(", "),
        }
    }

    /// The operator on the inputs' gradients, for a field computed from neighbouring cells
    /// ([`evaluate`](Self::evaluate) does not apply to it).
    pub fn operator(&self) -> Option<Operator> {
        match &self.computation {
            Computation::Differential(op, _) => Some(*op),
            _ => None,
        }
    }

    /// The formula's value for the input values `values` (in [`inputs`](Self::inputs) order)
    /// at a cell, computed in double precision; NaN for an [`operator`](Self::operator).
    pub fn evaluate(&self, values: &[f64]) -> f64 {
        match &self.computation {
            Computation::Differential(..) => f64::NAN,
            Computation::Magnitude(_) => values.iter().map(|v| v * v).sum::<f64>().sqrt(),
            // The values are as many as the formula's variables, so evaluation cannot fail; a
            // failure would be a bug of this module, reported as NaN and refused by the caller.
            Computation::Expression(expr) => expr.eval(values).unwrap_or(f64::NAN),
        }
    }
}

impl fmt::Display for DerivedField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}={}", self.name, self.formula)
    }
}

/// Names every derived field once: refuses two of one name.
pub fn check_distinct(derived: &[DerivedField]) -> Result<(), DeriveError> {
    for (i, d) in derived.iter().enumerate() {
        if derived[..i].iter().any(|e| e.name == d.name) {
            return Err(DeriveError::NameTaken {
                name: d.name.clone(),
                why: "two derived fields have that name".into(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn a_magnitude_is_the_length_of_its_fields_vector() {
        let d: DerivedField = "speed = |x-velocity,y-velocity,z-velocity|"
            .parse()
            .unwrap();
        assert_eq!(d.name(), "speed");
        assert_eq!(d.inputs(), ["x-velocity", "y-velocity", "z-velocity"]);
        let fields = names(&["Density", "z-velocity", "x-velocity", "y-velocity"]);
        assert_eq!(d.bind(&fields).unwrap(), [2, 3, 1]);
        assert_eq!(d.evaluate(&[3.0, 4.0, 12.0]), 13.0);
        assert_eq!(d.to_string(), "speed=|x-velocity,y-velocity,z-velocity|");
    }

    #[test]
    fn an_expression_reads_its_fields_in_the_order_inputs_lists_them() {
        let d: DerivedField = "T=pressure/density*{mean-mass}".parse().unwrap();
        let order = d.inputs().to_vec();
        let value = |name: &str| match name {
            "pressure" => 6.0,
            "density" => 2.0,
            "mean-mass" => 0.5,
            _ => unreachable!(),
        };
        let values: Vec<f64> = order.iter().map(|n| value(n)).collect();
        assert_eq!(d.evaluate(&values), 1.5);
        let d: DerivedField = "k=0.5*rho*2.5e-1*1E+2/.5e2".parse().unwrap();
        assert_eq!(d.inputs(), ["rho"]);
        assert_eq!(d.evaluate(&[4.0]), 0.5 * 4.0 * 0.25 * 100.0 / 50.0);
        let d: DerivedField = "lr=log10(rho)+sqrt(abs(min(a,b)))".parse().unwrap();
        let values: Vec<f64> = d
            .inputs()
            .iter()
            .map(|n| match n.as_str() {
                "rho" => 100.0,
                "a" => -4.0,
                "b" => 9.0,
                _ => unreachable!(),
            })
            .collect();
        assert_eq!(d.evaluate(&values), 4.0);
    }

    #[test]
    fn differential_operators_name_their_fields() {
        let d: DerivedField = "w = curl(x-velocity, {y-velocity},z-velocity)"
            .parse()
            .unwrap();
        assert_eq!(d.operator(), Some(Operator::Curl));
        assert_eq!(d.inputs(), ["x-velocity", "y-velocity", "z-velocity"]);
        let d: DerivedField = "g=grad({Y(CH4)})".parse().unwrap();
        assert_eq!(
            (d.operator(), d.inputs()),
            (Some(Operator::Gradient), &["Y(CH4)".to_string()][..])
        );
        let d: DerivedField = "q=qcriterion(u,v,w)".parse().unwrap();
        assert_eq!(d.operator(), Some(Operator::QCriterion));
        let d: DerivedField = "g=grad2*u".parse().unwrap();
        assert_eq!(
            (d.operator(), d.inputs()),
            (None, &["grad2".to_string(), "u".into()][..])
        );
    }

    #[test]
    fn malformed_arguments_say_what_is_wrong() {
        for (given, says) in [
            ("speed", "expected NAME=FORMULA"),
            ("=a+b", "expected NAME=FORMULA"),
            ("s=", "expected NAME=FORMULA"),
            ("s=a+*", "cannot read the formula 'a+*'"),
            ("s=(a+b", "cannot read the formula"),
            ("s=|a|", "two or more fields between bars"),
            ("s=|a,|", "two or more fields between bars"),
            ("s=|a,b", "cannot read the formula"),
            ("s=2*PI", "reads no field"),
            ("s=curl(u,v)", "curl takes a vector's three fields"),
            ("s=grad(a,b)", "grad takes one field"),
            ("s=grad()", "grad takes one field"),
            ("s=2*grad(a)", "stand alone as a whole formula"),
            ("s=grad(a)+grad(b)", "stand alone as a whole formula"),
        ] {
            let e = given.parse::<DerivedField>().unwrap_err().to_string();
            assert!(e.contains(says), "{given}: {e}");
        }
    }

    #[test]
    fn a_missing_field_or_a_taken_name_is_named() {
        let fields = names(&["x-velocity", "Density"]);
        let d: DerivedField = "v=x-velocity^2".parse().unwrap();
        let e = d.bind(&fields).unwrap_err().to_string();
        assert!(e.contains("no field named 'velocity'"), "{e}");
        assert!(e.contains("written in braces: {x-velocity}"), "{e}");
        let d: DerivedField = "v=density*2".parse().unwrap();
        let e = d.bind(&fields).unwrap_err().to_string();
        assert!(e.contains("did you mean 'Density'"), "{e}");
        let d: DerivedField = "Density={x-velocity}".parse().unwrap();
        assert!(d.bind(&fields).is_ok());
        let e = d.check_name(&fields).unwrap_err().to_string();
        assert!(e.contains("exists already"), "{e}");
        let twice: Vec<DerivedField> = ["a={x-velocity}", "a=Density"]
            .iter()
            .map(|s| s.parse().unwrap())
            .collect();
        let e = check_distinct(&twice).unwrap_err().to_string();
        assert!(e.contains("two derived fields"), "{e}");
    }
}

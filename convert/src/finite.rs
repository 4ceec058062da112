//! Checked conversion of stored values to the finite `f32` values an `.amrk` file holds.

/// A stored value type that converts to a finite `f32`, or says why it cannot.
pub trait ToFiniteF32: Copy {
    /// The value as a finite `f32` (doubles rounded to nearest), or why not ("NaN",
    /// "infinite", "outside the f32 range") with the value.
    fn to_finite_f32(self) -> Result<f32, (&'static str, f64)>;
}

impl ToFiniteF32 for f32 {
    fn to_finite_f32(self) -> Result<f32, (&'static str, f64)> {
        if self.is_finite() {
            Ok(self)
        } else {
            Err((if self.is_nan() { "NaN" } else { "infinite" }, self as f64))
        }
    }
}

impl ToFiniteF32 for f64 {
    fn to_finite_f32(self) -> Result<f32, (&'static str, f64)> {
        let v = self as f32;
        if v.is_finite() {
            Ok(v)
        } else if self.is_nan() {
            Err(("NaN", self))
        } else if self.is_infinite() {
            Err(("infinite", self))
        } else {
            Err(("outside the f32 range", self))
        }
    }
}

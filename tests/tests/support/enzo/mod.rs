//! Enzo datasets written by the tests themselves, in the layout Enzo's own writers produce
//! (`WriteParameterFile.C`, `Group_WriteDataHierarchy.C`, `Grid_Group_WriteGrid.C`), and the
//! values they store.
pub mod writer;

/// The value the fixtures store at a valid cell of `level`: smooth, different per level and
/// field, and (as f64) not exactly an f32.
pub fn value(level: usize, field: usize, p: [i64; 3]) -> f64 {
    let [x, y, z] = p.map(|v| v as f64);
    (field as f64 + 1.0) * ((0.29 * x - 0.83 * y + 0.57 * z).cos() * 7.0 + level as f64 * 50.0)
        + 1.0 / 7.0
}

/// The value a fixture stores in a ghost zone: far from every valid value.
pub fn ghost_value() -> f64 {
    -9.0e6
}

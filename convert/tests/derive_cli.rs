//! `amr-convert --derive NAME=FORMULA` on the real dumps: each derived value is the formula of
//! the stored values at its cell (computed here by hand, not by the converter's parser), the
//! other fields are the plain conversion's bit for bit, and bad formulas are refused with the
//! file, the field and the cell named. Also an `.amrk` input rewritten.

// The integration tests' support code: fixture writers and the shared-data folder.
#[path = "../../tests/tests/support/mod.rs"]
#[allow(dead_code)]
mod support;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use amr_format::AmrkFile;
use amr_render::shade::IsoSpec;
use amr_render::{render, Scene, SceneOptions, View};

const BIN: &str = env!("CARGO_BIN_EXE_amr-convert");

/// The active octants of field `field` of `path` at `iso`, and the frame's colours from the
/// default camera framing them.
fn surface(path: &Path, field: &str, iso: f32) -> (u64, [Vec<f32>; 3]) {
    let options = SceneOptions {
        field: Some(field.into()),
        ..SceneOptions::default()
    };
    let mut scene = Scene::open(path, &options).unwrap();
    scene.set_isosurfaces(&[IsoSpec::new(iso)]).unwrap();
    let view = View {
        size: (64, 48),
        ..View::default()
    };
    let frame = render(&scene, &view, &|_| {}).unwrap().frame;
    assert!(frame.covered() > 0, "{field} = {iso} is not seen");
    (scene.stats().active_octants, frame.rgb)
}

fn run(bin: &str, args: &[&str]) -> Output {
    Command::new(bin).args(args).output().unwrap()
}

/// `amr-convert args...`, which must succeed.
fn convert(args: &[&str]) {
    let o = run(BIN, args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `amr-convert args...`, which must fail with exit status 1; its message.
fn refused(args: &[&str]) -> String {
    let o = run(BIN, args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn open(path: &Path) -> AmrkFile<Vec<u8>> {
    AmrkFile::open(std::fs::read(path).unwrap()).unwrap()
}

fn names(file: &AmrkFile<Vec<u8>>) -> Vec<String> {
    file.fields().iter().map(|f| f.name.clone()).collect()
}

/// Every brick's values of field `name`, brick after brick.
fn values(file: &AmrkFile<Vec<u8>>, name: &str) -> Vec<Vec<f32>> {
    let f = file.field_index(name).unwrap();
    (0..file.num_bricks())
        .map(|b| file.brick_values(f, b).unwrap().into_owned())
        .collect()
}

/// The cell at position `k` (x fastest) of a brick of cells `cells`.
fn cell_of(cells: &amr_format::IBox, k: usize) -> [i64; 3] {
    let [nx, ny, _] = cells.extent();
    let k = k as i64;
    let offset = [k % nx, (k / nx) % ny, k / (nx * ny)];
    [0, 1, 2].map(|a| cells.lo[a] + offset[a])
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn enzo(test: &str) -> Option<PathBuf> {
    support::amrex::shared_data(test, "enzo/DD0010", "moving7_0010")
}

#[test]
fn a_derived_speed_is_the_length_of_the_stored_velocity_at_every_cell() {
    let Some(dd) = enzo("a_derived_speed_is_the_length_of_the_stored_velocity_at_every_cell")
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (plain, derived) = (dir.path().join("plain.amrk"), dir.path().join("d.amrk"));
    convert(&[s(&dd), "-o", s(&plain)]);
    convert(&[
        s(&dd),
        "-o",
        s(&derived),
        "--derive",
        "speed=|x-velocity,y-velocity,z-velocity|",
        "--derive",
        "ratio = Density / ({Dark_Matter_Density} + 1e-3) * 2.5E-1",
        "--derive",
        "lspeed=log10(speed)",
    ]);
    let (plain, derived) = (open(&plain), open(&derived));
    let mut expected = names(&plain);
    expected.extend(["speed".into(), "ratio".into(), "lspeed".into()]);
    assert_eq!(names(&derived), expected);
    assert_eq!(plain.num_bricks(), derived.num_bricks());
    for b in 0..plain.num_bricks() {
        assert_eq!(plain.brick(b), derived.brick(b));
    }
    for name in names(&plain) {
        assert_eq!(values(&plain, &name), values(&derived, &name), "{name}");
    }
    assert_eq!(plain.simulation_time(), derived.simulation_time());
    assert_eq!(plain.simulation_step(), derived.simulation_step());
    assert!(derived.has_tight_ranges());
    let component = |n: &str| values(&plain, n).concat();
    let (vx, vy, vz) = (
        component("x-velocity"),
        component("y-velocity"),
        component("z-velocity"),
    );
    let (rho, dm) = (component("Density"), component("Dark_Matter_Density"));
    let (speed, ratio, lspeed) = (
        values(&derived, "speed").concat(),
        values(&derived, "ratio").concat(),
        values(&derived, "lspeed").concat(),
    );
    assert_eq!(speed.len(), 30_360);
    for i in 0..speed.len() {
        let [x, y, z] = [vx[i], vy[i], vz[i]].map(f64::from);
        assert_eq!(speed[i], (x * x + y * y + z * z).sqrt() as f32, "cell {i}");
        let r = f64::from(rho[i]) / (f64::from(dm[i]) + 1e-3) * 0.25;
        assert_eq!(ratio[i], r as f32, "cell {i}");
        // A formula reads a field derived before it, as stored.
        assert_eq!(lspeed[i], f64::from(speed[i]).log10() as f32, "cell {i}");
    }
    // The derived field is contoured like any other.
    let (active, _) = surface(&dir.path().join("d.amrk"), "speed", 1.0);
    assert!(active > 100, "{active}");
}

/// With `--field`, the formulas' fields are read but only the fields asked for are stored; and
/// an AMReX plotfile's field names with brackets are written in braces.
#[test]
fn the_fields_a_formula_reads_need_not_be_stored() {
    let test = "the_fields_a_formula_reads_need_not_be_stored";
    let Some(amrex) = support::amrex::shared_amrex(test) else {
        return;
    };
    let plt = amrex.join("example_plt_3d");
    let dir = tempfile::tempdir().unwrap();
    let (all, some) = (dir.path().join("all.amrk"), dir.path().join("some.amrk"));
    convert(&[s(&plt), "-o", s(&all)]);
    convert(&[
        s(&plt),
        "-o",
        s(&some),
        "--field",
        "temp",
        "--derive",
        "ke=0.5*density*(x_velocity^2+y_velocity^2+z_velocity^2)",
        "--derive",
        "fuel={Y(CH4)}+{Y(H2)}",
        "--compress",
    ]);
    let (all, some) = (open(&all), open(&some));
    assert_eq!(names(&some), ["temp", "ke", "fuel"]);
    assert!(some.fields().iter().all(|f| f.compressed));
    assert_eq!(values(&all, "temp"), values(&some, "temp"));
    let column = |n: &str| values(&all, n).concat();
    let (rho, vx, vy, vz) = (
        column("density"),
        column("x_velocity"),
        column("y_velocity"),
        column("z_velocity"),
    );
    let (ch4, h2) = (column("Y(CH4)"), column("Y(H2)"));
    let (ke, fuel) = (values(&some, "ke").concat(), values(&some, "fuel").concat());
    for i in 0..ke.len() {
        let v2 = [vx[i], vy[i], vz[i]]
            .map(f64::from)
            .iter()
            .map(|v| v * v)
            .sum::<f64>();
        assert_eq!(ke[i], (0.5 * f64::from(rho[i]) * v2) as f32, "cell {i}");
        assert_eq!(fuel[i], (f64::from(ch4[i]) + f64::from(h2[i])) as f32);
    }
}

/// An `.amrk` file given as input is written anew: fields dropped or derived, bricks
/// compressed; a kept field renders the same picture as from the original.
#[test]
fn an_amrk_input_is_rewritten_with_its_bricks_as_they_are() {
    let Some(dd) = enzo("an_amrk_input_is_rewritten_with_its_bricks_as_they_are") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first.amrk");
    convert(&[s(&dd), "-o", s(&first)]);
    let second = dir.path().join("second.amrk");
    convert(&[
        s(&first),
        "-o",
        s(&second),
        "--field",
        "Density",
        "--derive",
        "speed=|x-velocity,y-velocity,z-velocity|",
        "--compress",
    ]);
    let (a, b) = (open(&first), open(&second));
    assert_eq!(names(&b), ["Density", "speed"]);
    assert_eq!(values(&a, "Density"), values(&b, "Density"));
    assert_eq!(
        surface(&first, "Density", 30.0),
        surface(&second, "Density", 30.0)
    );
    // Options that would change the bricks do not apply.
    for option in [&["--brick", "16"][..], &["--keep-boxes"]] {
        let e = refused(&[&[s(&first), "-o", s(&dir.path().join("x.amrk"))], option].concat());
        assert!(
            e.contains(&format!(
                "keeps its bricks, so {} does not apply",
                option[0]
            )),
            "{e}"
        );
    }
    // A field derived in one run is derived from in the next, by a gradient too.
    let third = dir.path().join("third.amrk");
    convert(&[s(&second), "-o", s(&third), "--derive", "g=grad(speed)"]);
    assert_eq!(names(&open(&third)), ["Density", "speed", "g"]);
    let e = refused(&[s(&first), "-o", s(&first), "--field", "Density"]);
    assert!(e.contains("refusing to replace it"), "{e}");
}

#[test]
fn bad_formulas_are_refused_naming_the_field_and_the_cell() {
    let Some(dd) = enzo("bad_formulas_are_refused_naming_the_field_and_the_cell") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.amrk");
    for (derive, says) in [
        ("speed", "expected NAME=FORMULA"),
        ("s=Density*", "cannot read the formula 'Density*'"),
        ("s=x-velocity^2", "no field named 'velocity'"),
        ("s=x-velocity^2", "written in braces: {x-velocity}"),
        ("s=density", "(did you mean 'Density'?)"),
        (
            "Density={x-velocity}",
            "a field of that name exists already",
        ),
        (
            "l=ln({x-velocity}-0.7)",
            "the derived field l = ln({x-velocity}-0.7) is NaN at level 0, cell [0, 0, 0], \
             where x-velocity = ",
        ),
        ("big=Density*1e38", "is outside the f32 range (3."),
        ("inf=1/(Temperature-1)", "is infinite at level 0, cell ["),
    ] {
        let e = refused(&[s(&dd), "-o", s(&out), "--derive", derive]);
        assert!(e.contains(says), "{derive}: {e}");
        // The dump is named (unless the argument itself is malformed), never the intermediate
        // file the dump is first converted into.
        assert!(
            (e.contains("DD0010") || e.contains("invalid value")) && !e.contains(".tmp"),
            "{derive}: {e}"
        );
        assert!(!out.exists(), "{derive}: an output was left");
    }
    let e = refused(&[
        s(&dd),
        "-o",
        s(&out),
        "--derive",
        "a=Density",
        "--derive",
        "a=Temperature",
    ]);
    assert!(e.contains("two derived fields have that name"), "{e}");
    let e = refused(&[
        s(&dd),
        "-o",
        s(&out),
        "--derive",
        "a=2*Density",
        "--derive",
        "g=grad(a)",
    ]);
    assert!(
        e.contains("'a' is derived in this run, and an operator on gradients reads stored"),
        "{e}"
    );
    // Neither the intermediate file nor any other temporary is left beside the output.
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}

/// `--update` keeps a file that has the derived fields and converts one that lacks them.
#[test]
fn an_update_converts_again_when_a_derived_field_is_missing() {
    let Some(dd) = enzo("an_update_converts_again_when_a_derived_field_is_missing") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("dd.amrk");
    let update = |extra: &[&str]| {
        let o = run(BIN, &[&[s(&dd), "-o", s(&out), "--update"], extra].concat());
        assert!(o.status.success());
        String::from_utf8_lossy(&o.stderr).contains("up to date, kept")
    };
    assert!(!update(&[]));
    assert!(update(&[]));
    assert!(!update(&["--derive", "s=|x-velocity,y-velocity|"]));
    assert!(update(&["--derive", "s=|x-velocity,y-velocity|"]));
    assert!(!update(&["--field", "Density", "--derive", "s=2*Density"]));
    assert!(update(&["--field", "Density", "--derive", "s=2*Density"]));
    assert!(!update(&["--field", "Density"]));
}

/// `grad`, `curl` and `qcriterion` of linear fields on three levels of mixed ratios with
/// anisotropic cells: exact at every leaf cell, next to level boundaries and on the domain's
/// faces too (where a neighbour is finer, coarser or missing), as a least-squares gradient
/// through the neighbours' own centres is. Covered cells hold 1e6: a leaf cell's gradient that
/// read one would be far off.
#[test]
fn differential_operators_are_exact_for_linear_fields_across_levels() {
    use support::amrex::writer::{write_plotfile, Bx, PlotSpec};
    let b = |lo: [i64; 3], hi: [i64; 3]| -> Bx { (lo, hi) };
    let spec = PlotSpec {
        fields: vec!["u".into(), "v".into(), "w".into(), "Y(CH4) [mass]".into()],
        prob_lo: [-2.0, -1.0, 0.0],
        prob_hi: [1.2, 0.6, 0.8],
        domain: ([0; 3], [15; 3]),
        ratios: vec![[2, 2, 2], [4, 4, 4]],
        boxes: vec![
            vec![b([0, 0, 0], [7, 15, 15]), b([8, 0, 0], [15, 15, 15])],
            vec![b([8, 8, 8], [23, 23, 23]), b([24, 8, 8], [31, 15, 15])],
            vec![b([48, 48, 48], [79, 79, 79])],
        ],
        ..PlotSpec::single(16)
    };
    let centre = |l: usize, i: [i64; 3]| {
        let (lo, _) = spec.level_domain(l);
        let dx = spec.cell_size(l);
        [0, 1, 2].map(|a| spec.prob_lo[a] + ((i[a] - lo[a]) as f64 + 0.5) * dx[a])
    };
    // Whether level `l`'s cell `i` lies under a box of the next finer level.
    let covered = |l: usize, i: [i64; 3]| {
        let (Some(finer), Some(r)) = (spec.boxes.get(l + 1), spec.ratios.get(l)) else {
            return false;
        };
        finer
            .iter()
            .any(|(lo, hi)| (0..3).all(|a| i[a] * r[a] <= hi[a] && (i[a] + 1) * r[a] > lo[a]))
    };
    let value = |l: usize, c: usize, i: [i64; 3]| {
        // Covered cells hold nothing a leaf cell's gradient may read.
        if covered(l, i) {
            return 1e6;
        }
        let [x, y, z] = centre(l, i);
        match c {
            0 => -2.0 * y + z,
            1 => 2.0 * x,
            2 => 3.0 * x - y,
            _ => 0.5 * x - 3.0 * y + 2.0 * z,
        }
    };
    let dir = tempfile::tempdir().unwrap();
    let plt = dir.path().join("plt00000");
    write_plotfile(&plt, &spec, &value, f64::NAN);
    let out = dir.path().join("ops.amrk");
    convert(&[
        s(&plt),
        "-o",
        s(&out),
        "--brick",
        "8",
        "--derive",
        "vort=curl(u,v,w)",
        "--derive",
        "q=qcriterion(u,v,w)",
        "--derive",
        "g=grad({Y(CH4) [mass]})",
        "--derive",
        "dv=div(u,v,w)",
        "--derive",
        "d=dv+1",
    ]);
    let file = open(&out);
    assert_eq!(file.levels().len(), 3);
    // The divergence of this velocity is 0: `d` adds 1 so that the error is relative to 1.
    let expected = [
        ("vort", 21f64.sqrt()),
        ("q", 1.0),
        ("g", 13.25f64.sqrt()),
        ("d", 1.0),
    ];
    for (name, exact) in expected {
        let mut leaf_cells = 0;
        for (b, brick) in values(&file, name).iter().enumerate() {
            let info = file.brick(b);
            for (k, &v) in brick.iter().enumerate() {
                let cell = cell_of(&info.cells, k);
                if covered(info.level as usize, cell) {
                    continue;
                }
                let error = (f64::from(v) - exact).abs() / exact;
                assert!(
                    error < 1e-4,
                    "{name} at level {} cell {cell:?}: {v}",
                    info.level
                );
                leaf_cells += 1;
            }
        }
        assert!(leaf_cells > 30_000, "{leaf_cells}");
    }
}

/// PeleLM writes its own vorticity, `mag_vort`, beside the velocity in `example_plt_3d`: the
/// derived `curl` equals it on every cell of the finest level (which covers this domain) off the
/// domain's faces, where PeleLM differences into its boundary's ghost cells and this
/// converter takes one side.
#[test]
fn a_derived_vorticity_equals_pelelms_own_on_the_finest_cells() {
    let test = "a_derived_vorticity_equals_pelelms_own_on_the_finest_cells";
    let Some(amrex) = support::amrex::shared_amrex(test) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("vort.amrk");
    convert(&[
        s(&amrex.join("example_plt_3d")),
        "-o",
        s(&out),
        "--field",
        "mag_vort",
        "--derive",
        "vort=curl(x_velocity,y_velocity,z_velocity)",
    ]);
    let file = open(&out);
    let finest = file.levels().len() as u32 - 1;
    let domain = file.levels()[finest as usize].domain;
    let (theirs, ours) = (values(&file, "mag_vort"), values(&file, "vort"));
    let largest = file.fields()[0].max;
    let mut compared = 0;
    for b in 0..file.num_bricks() {
        let cells = file.brick(b).cells;
        if file.brick(b).level != finest {
            continue;
        }
        for (i, (t, o)) in theirs[b].iter().zip(&ours[b]).enumerate() {
            let at = cell_of(&cells, i);
            if (0..3).any(|a| at[a] == domain.lo[a] || at[a] + 1 == domain.hi[a]) {
                continue;
            }
            assert!(
                (t - o).abs() <= 1e-4 * t + 1e-6 * largest,
                "cell {at:?}: PeleLM {t}, derived {o}"
            );
            compared += 1;
        }
    }
    assert!(compared > 20_000, "{compared}");
}

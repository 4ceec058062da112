//! Opening a Chombo file (plotfile or checkpoint): the root attributes, every level's geometry,
//! boxes and offsets, all validated before any cell data is read.
//!
//! A level's data is one or more `LevelData` written by `CH_HDF5`'s `write(handle, data, NAME,
//! outputGhost)`: `NAME:datatype=0`, `NAME:offsets=0` and the group `NAME_attributes`.
//! Plotfiles and most checkpoints (GRChombo's, Chombo's example `AMRLevel`s) write one, `data`,
//! holding every component named at the root; other checkpoints write one per variable.
//!
//! AMReX's HDF5 plotfiles (`WriteMultiLevelPlotfileHDF5`, `plotfile_type = "VanillaHDF5"`) use
//! the same layout with a few differences, each read as AMReX writes it ([`Writer::AmrexHdf5`]).

use std::path::{Path, PathBuf};

use amr_format::hierarchy::MAX_LEVELS;
use amr_format::{IBox, LevelSpec};
use hdf5_metno::types::{FloatSize, TypeDescriptor};
use hdf5_metno::{Dataset, File};

use super::error::{ChomboError, Result};
use super::props::{check_members, Props, ROOT};
use super::raw::{self, RawBox, RawIntVect, RawRealVect};
use super::reader::stream;
use crate::hierarchy_to_amrk::{AmrSource, Slab};
use amr_format::progress::Progress;

/// Most components accepted (a sanity bound on a count read from the file).
const MAX_COMPONENTS: i64 = 4096;

/// How the cell values are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Precision {
    /// IEEE single precision.
    F32,
    /// IEEE double precision (rounded to nearest `f32` on conversion).
    F64,
}

impl Precision {
    /// Bytes per value.
    pub fn bytes(self) -> u64 {
        match self {
            Precision::F32 => 4,
            Precision::F64 => 8,
        }
    }
}

/// One `LevelData` of a level: a dataset of every box's values and where each box starts.
#[derive(Debug)]
pub struct LevelVar {
    /// Components stored per box.
    pub ncomp: usize,
    /// Ghost layers stored around every box (`outputGhost`).
    pub ghost: [i64; 3],
    /// Where each box's data starts in the dataset, in values; `boxes.len() + 1` entries.
    pub offsets: Vec<u64>,
    /// How the values are stored.
    pub precision: Precision,
    /// The `NAME:datatype=0` dataset (absent only when the level has no boxes).
    pub(crate) data: Option<Dataset>,
}

impl LevelVar {
    /// The box `valid` with this data's ghost layers: the cells its data covers.
    pub fn stored_box(&self, valid: &IBox) -> IBox {
        valid.grow(self.ghost)
    }
}

/// Which code wrote the file: Chombo's layout as AMReX's HDF5 writer follows it differs in a
/// few attributes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Writer {
    /// Chombo's `CH_HDF5` (`WriteAMRHierarchyHDF5`, checkpoints): cell index 0 at position 0,
    /// the cell size in `dx` (or `vec_dx`), ghost layers in `NAME_attributes/outputGhost`.
    Chombo,
    /// AMReX's `WriteMultiLevelPlotfileHDF5` (`Src/Extern/HDF5/AMReX_PlotFileUtilHDF5.cpp`):
    /// the domain's lower corner at `prob_lo`, the cell size per axis in `Vec_dx` (`dx` holds
    /// only x's), `ref_ratio` only x's ratio (the others come from the level domains), no
    /// `data_attributes` group (valid cells only, no ghosts), `domain_type` and
    /// `coordinate_system` (cell-centred Cartesian data only), the step in `steps`.
    AmrexHdf5,
}

/// One level of a file, validated.
#[derive(Debug)]
pub struct Level {
    /// Cell size on each axis.
    pub dx: [f64; 3],
    /// Physical position of the lower corner of cell index (0, 0, 0).
    pub origin: [f64; 3],
    /// Refinement ratio to the next finer level (`[1, 1, 1]` on the finest).
    pub ref_ratio: [u32; 3],
    /// The problem domain in this level's index space (half-open).
    pub domain: IBox,
    /// The boxes' valid cells (half-open), in file order.
    pub boxes: Vec<IBox>,
    /// The level's data, one entry per name of [`Plotfile::vars`].
    pub vars: Vec<LevelVar>,
}

/// Where a field's values are: which `LevelData` and which of its components.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FieldSource {
    /// Index into [`Plotfile::vars`].
    pub var: usize,
    /// Component within that data.
    pub comp: usize,
}

/// An open Chombo file: its fields and levels, checked for consistency.
#[derive(Debug)]
pub struct Plotfile {
    /// The HDF5 file.
    pub path: PathBuf,
    /// Field names, in file order.
    pub fields: Vec<String>,
    /// Where each field's values are.
    pub sources: Vec<FieldSource>,
    /// The names of each level's `LevelData` (`data` in plotfiles).
    pub vars: Vec<String>,
    /// Levels, coarsest first.
    pub levels: Vec<Level>,
    /// The simulation time (level 0's `time` attribute, which Chombo's writers set), if any.
    pub time: Option<f64>,
    /// The simulation step (level 0's `steps`, which AMReX's writer sets), if any.
    pub step: Option<i64>,
    /// Which code wrote the file.
    pub writer: Writer,
    _file: File,
}

impl Plotfile {
    /// Opens and validates the plotfile at `path`; reads metadata only.
    pub fn open(path: &Path) -> Result<Self> {
        let io = |source| ChomboError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file_len = std::fs::File::open(path)
            .and_then(|f| f.metadata())
            .map_err(io)?
            .len();
        let file = File::open(path)
            .map_err(|e| ChomboError::hdf5(path, "cannot open as an HDF5 file", e))?;
        let root = Props::new(path, (*file).clone(), ROOT)?;
        let writer = match root.has(raw::PLOTFILE_TYPE)
            && root.string(raw::PLOTFILE_TYPE)? == raw::AMREX_PLOTFILE_TYPE
        {
            true => Writer::AmrexHdf5,
            false => Writer::Chombo,
        };
        if writer == Writer::AmrexHdf5 && root.has(raw::COORDINATE_SYSTEM) {
            let coord = root.int(raw::COORDINATE_SYSTEM)?;
            if coord != 0 {
                return Err(ChomboError::unsupported(
                    path,
                    format!(
                        "coordinate_system = {coord} (0 is Cartesian, 1 cylindrical, 2 \
                         spherical): only Cartesian data can be converted"
                    ),
                ));
            }
        }
        let global = root.child(raw::GLOBAL_GROUP)?;
        let dim = global.int(raw::SPACE_DIM)?;
        if dim != 3 {
            return Err(ChomboError::unsupported(
                path,
                format!("a {dim}D file (Chombo_global/SpaceDim = {dim}); only 3D files can be converted"),
            ));
        }
        let Layout {
            vars,
            fields,
            sources,
        } = read_layout(path, &root, writer)?;
        let nl = root.int(raw::NUM_LEVELS)?;
        if !(1..=MAX_LEVELS as i64).contains(&nl) {
            return Err(root.invalid(format!("num_levels = {nl}, expected 1 to {MAX_LEVELS}")));
        }
        // A label only: a missing or unreadable time leaves the output unlabelled.
        let time = root
            .child(&raw::level(0))
            .ok()
            .filter(|g| g.has("time"))
            .and_then(|g| g.float("time").ok())
            .filter(|t| t.is_finite());
        // A label only, as the time.
        let step = root
            .child(&raw::level(0))
            .ok()
            .filter(|g| writer == Writer::AmrexHdf5 && g.has(raw::STEPS))
            .and_then(|g| g.int(raw::STEPS).ok());
        let mut levels: Vec<Level> = Vec::with_capacity(nl as usize);
        for l in 0..nl as usize {
            let g = root.child(&raw::level(l))?;
            let level = read_level(&g, l + 1 == nl as usize, &vars, file_len, writer)?;
            if let Some(prev) = levels.last_mut() {
                if writer == Writer::AmrexHdf5 {
                    prev.ref_ratio = ratio_of_domains(&g, l, prev, &level)?;
                }
                check_refinement(&g, l, prev, &level)?;
            }
            levels.push(level);
        }
        let vars = vars.into_iter().map(|v| v.name).collect();
        Ok(Self {
            path: path.to_path_buf(),
            fields,
            sources,
            vars,
            levels,
            time,
            step,
            writer,
            _file: file,
        })
    }

    /// The levels as the `.amrk` writer wants them. Chombo puts the lower corner of cell index
    /// 0 at physical position 0, so its levels' origins are zero and the domain's lower corner
    /// lands at `dx * prob_domain.lo`; AMReX puts the domain's lower corner at `prob_lo`.
    pub fn level_specs(&self) -> Vec<LevelSpec> {
        self.levels
            .iter()
            .map(|l| LevelSpec {
                cell_size: l.dx,
                origin: l.origin,
                ratio_to_next: l.ref_ratio,
                domain: l.domain,
            })
            .collect()
    }
}

impl AmrSource for Plotfile {
    type Error = ChomboError;

    fn path(&self) -> &Path {
        &self.path
    }

    fn fields(&self) -> &[String] {
        &self.fields
    }

    fn simulation(&self) -> (Option<f64>, Option<i64>) {
        (self.time, self.step)
    }

    fn level_specs(&self) -> Vec<LevelSpec> {
        Plotfile::level_specs(self)
    }

    fn boxes(&self) -> Vec<&[IBox]> {
        self.levels.iter().map(|l| l.boxes.as_slice()).collect()
    }

    fn stream(
        &self,
        comps: &[usize],
        chunk: i64,
        progress: &dyn Progress,
        sink: &mut dyn FnMut(Slab) -> Result<()>,
    ) -> Result<u64> {
        Ok(stream(self, comps, chunk, progress, sink)?.bytes_read)
    }
}

/// The file's `LevelData` names with their component counts, its field names, and where each
/// field is. With `data:datatype=0` in `level_0` (plotfiles, GRChombo checkpoints) the fields
/// are the root's `component_N`, all in `data`. Otherwise every `NAME:datatype=0` of `level_0`
/// is a variable of `NAME_attributes/comps` components, named `NAME` when it has one, `xNAME`,
/// `yNAME`, `zNAME` when the root's `component_N` list names them so, else `NAME_0`, `NAME_1`,
/// ...; fields follow the root list's order where there is one. An AMReX HDF5 plotfile with
/// `data:datatype=1` is of the writer's one-dataset-per-component variant
/// ([`VarSpec::amrex_component`]).
fn read_layout(path: &Path, root: &Props, writer: Writer) -> Result<Layout> {
    let l0 = raw::level(0);
    let level0 = if root.has_member(&l0) {
        Some(root.child(&l0)?)
    } else {
        None
    };
    let datasets: Vec<String> = match &level0 {
        Some(g) => g
            .member_names()?
            .into_iter()
            .filter_map(|m| m.strip_suffix(raw::DATATYPE_SUFFIX).map(str::to_string))
            .collect(),
        None => Vec::new(),
    };
    if !root.has(raw::NUM_LEVELS) && datasets.is_empty() {
        return Err(ChomboError::NoData {
            path: path.to_path_buf(),
            why: match level0 {
                Some(_) => {
                    "the root has no num_levels and level_0 holds no NAME:datatype=0 dataset \
                            (a file of boxes only, such as Chombo's meshRefineTest writes)"
                        .into()
                }
                None => "the root has no num_levels and there is no level_0 group".into(),
            },
        });
    }
    let listed = component_list(root)?;
    let per_component = format!("{}:datatype=1", raw::DATA_NAME);
    if let (Writer::AmrexHdf5, Some(g)) = (writer, &level0) {
        if g.has_member(&per_component) {
            let Some(fields) = listed else {
                return Err(root.invalid(format!("missing attribute '{}'", raw::NUM_COMPONENTS)));
            };
            return Ok(Layout {
                vars: (0..fields.len()).map(VarSpec::amrex_component).collect(),
                sources: (0..fields.len())
                    .map(|var| FieldSource { var, comp: 0 })
                    .collect(),
                fields,
            });
        }
    }
    let g = match level0 {
        Some(g) if !datasets.iter().any(|d| d == raw::DATA_NAME) => g,
        _ => {
            let Some(fields) = listed else {
                return Err(root.invalid(format!("missing attribute '{}'", raw::NUM_COMPONENTS)));
            };
            return Ok(Layout {
                vars: vec![VarSpec::chombo(raw::DATA_NAME, fields.len())],
                sources: (0..fields.len())
                    .map(|comp| FieldSource { var: 0, comp })
                    .collect(),
                fields,
            });
        }
    };
    let mut vars = Vec::with_capacity(datasets.len());
    let mut candidates: Vec<(String, FieldSource)> = Vec::new();
    for (v, name) in datasets.iter().enumerate() {
        let attrs = g.child(&format!("{name}{}", raw::ATTRIBUTES_SUFFIX))?;
        let comps = attrs.int(raw::COMPS)?;
        if !(1..=MAX_COMPONENTS).contains(&comps) {
            return Err(attrs.invalid(format!("comps = {comps}, expected 1 to {MAX_COMPONENTS}")));
        }
        let comps = comps as usize;
        let axes: Vec<String> = ["x", "y", "z"]
            .iter()
            .map(|a| format!("{a}{name}"))
            .collect();
        let named_by_axis = comps <= 3
            && comps > 1
            && listed
                .as_ref()
                .is_some_and(|l| axes[..comps].iter().all(|a| l.contains(a)));
        for comp in 0..comps {
            let field = if comps == 1 {
                name.clone()
            } else if named_by_axis {
                axes[comp].clone()
            } else {
                format!("{name}_{comp}")
            };
            candidates.push((field, FieldSource { var: v, comp }));
        }
        vars.push(VarSpec::chombo(name, comps));
    }
    let mut order: Vec<usize> = Vec::with_capacity(candidates.len());
    if let Some(list) = &listed {
        for (c, name) in list.iter().enumerate() {
            let Some(i) = candidates.iter().position(|(f, _)| f == name) else {
                return Err(root.invalid(format!(
                    "component_{c} is '{name}', but level_0 holds no dataset for it (its datasets: {})",
                    datasets.join(", ")
                )));
            };
            order.push(i);
        }
    }
    let unlisted: Vec<usize> = (0..candidates.len())
        .filter(|i| !order.contains(i))
        .collect();
    order.extend(unlisted);
    let (fields, sources) = order.into_iter().map(|i| candidates[i].clone()).unzip();
    Ok(Layout {
        vars,
        fields,
        sources,
    })
}

/// How a file's fields are stored: what [`read_layout`] finds.
struct Layout {
    /// Each `LevelData`'s objects and component count.
    vars: Vec<VarSpec>,
    /// Field names, in order.
    fields: Vec<String>,
    /// Where each field is.
    sources: Vec<FieldSource>,
}

/// One `LevelData` as every level stores it: the HDF5 objects holding it and its components.
#[derive(Clone, Debug)]
struct VarSpec {
    /// Its name, as [`Plotfile::vars`] reports it.
    name: String,
    /// Components per box.
    comps: usize,
    /// The dataset of its values.
    data: String,
    /// The dataset of where each box's values start.
    offsets: String,
    /// The group of its attributes (ghost layers, components).
    attributes: String,
}

impl VarSpec {
    /// Chombo's `LevelData` `name`: `name:datatype=0`, `name:offsets=0`, `name_attributes`.
    fn chombo(name: &str, comps: usize) -> Self {
        VarSpec {
            name: name.to_string(),
            comps,
            data: format!("{name}{}", raw::DATATYPE_SUFFIX),
            offsets: format!("{name}{}", raw::OFFSETS_SUFFIX),
            attributes: format!("{name}{}", raw::ATTRIBUTES_SUFFIX),
        }
    }

    /// Component `j` of an AMReX HDF5 plotfile written by
    /// `WriteMultiLevelPlotfileHDF5MultiDset`: its values alone in `data:datatype=j`, the
    /// boxes' offsets in `data:offsets=0`, counted in cells (one component), shared by all.
    fn amrex_component(j: usize) -> Self {
        let mut spec = VarSpec::chombo(raw::DATA_NAME, 1);
        spec.data = format!("{}:datatype={j}", raw::DATA_NAME);
        spec.name = spec.data.clone();
        spec
    }
}

/// The root's `component_N` names when it has `num_components`, checked: non-empty, distinct.
fn component_list(root: &Props) -> Result<Option<Vec<String>>> {
    if !root.has(raw::NUM_COMPONENTS) {
        return Ok(None);
    }
    let nc = root.int(raw::NUM_COMPONENTS)?;
    if !(1..=MAX_COMPONENTS).contains(&nc) {
        return Err(root.invalid(format!(
            "num_components = {nc}, expected 1 to {MAX_COMPONENTS}"
        )));
    }
    let mut fields: Vec<String> = Vec::with_capacity(nc as usize);
    for c in 0..nc as usize {
        let name = root.string(&raw::component(c))?;
        if name.is_empty() {
            return Err(root.invalid(format!("component_{c} is an empty name")));
        }
        if let Some(d) = fields.iter().position(|f| *f == name) {
            return Err(root.invalid(format!(
                "component_{d} and component_{c} are both named '{name}'"
            )));
        }
        fields.push(name);
    }
    Ok(Some(fields))
}

/// Reads and checks one `level_N` group of a file of `file_len` bytes written by `writer`.
fn read_level(
    g: &Props,
    finest: bool,
    vars: &[VarSpec],
    file_len: u64,
    writer: Writer,
) -> Result<Level> {
    let amrex = writer == Writer::AmrexHdf5;
    let dx = if amrex && g.has(raw::AMREX_VEC_DX) {
        g.floats::<3>(raw::AMREX_VEC_DX)?
    } else if g.has(raw::DX) {
        [g.float(raw::DX)?; 3]
    } else if g.has(raw::VEC_DX) {
        let v: RawRealVect = g.compound(raw::VEC_DX, &raw::REALVECT_MEMBERS)?;
        [v.x, v.y, v.z]
    } else {
        return Err(g.invalid(format!("missing attribute '{}'", raw::DX)));
    };
    if dx.iter().any(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(g.invalid(format!("cell size dx = {dx:?} is not positive and finite")));
    }
    let ref_ratio = if finest && !g.has(raw::REF_RATIO) {
        [1; 3]
    } else {
        let r = match g.descriptor(raw::REF_RATIO)? {
            TypeDescriptor::Compound(_) => {
                let v: RawIntVect = g.compound(raw::REF_RATIO, &raw::INTVECT_MEMBERS)?;
                [v.intvecti, v.intvectj, v.intvectk].map(i64::from)
            }
            _ => [g.int(raw::REF_RATIO)?; 3],
        };
        if finest {
            [1; 3]
        } else if r.iter().any(|&x| !(2..=1024).contains(&x)) {
            return Err(g.invalid(format!(
                "ref_ratio = {r:?}, expected 2 to 1024 below the finest level"
            )));
        } else {
            r.map(|x| x as u32)
        }
    };
    let domain = to_ibox(g.compound::<RawBox>(raw::PROB_DOMAIN, &raw::BOX_MEMBERS)?);
    if domain.is_empty() {
        return Err(g.invalid(format!("empty prob_domain {}", show(&domain))));
    }
    if amrex && g.has(raw::DOMAIN_TYPE) {
        let centring = g.ints::<3>(raw::DOMAIN_TYPE)?;
        if centring != [0; 3] {
            return Err(g.unsupported(format!(
                "domain_type = {centring:?}: node- or face-centred data; only cell-centred data \
                 can be converted"
            )));
        }
    }
    let origin = match amrex && g.has(raw::PROB_LO) {
        true => {
            let lo = g.floats::<3>(raw::PROB_LO)?;
            if lo.iter().any(|x| !x.is_finite()) {
                return Err(g.invalid(format!("prob_lo = {lo:?} is not finite")));
            }
            [0, 1, 2].map(|a| lo[a] - domain.lo[a] as f64 * dx[a])
        }
        false => [0.0; 3],
    };
    let boxes = read_boxes(g, &domain, file_len)?;
    let vars = vars
        .iter()
        .map(|spec| read_var(g, spec, &boxes, writer))
        .collect::<Result<Vec<_>>>()?;
    Ok(Level {
        dx,
        origin,
        ref_ratio,
        domain,
        boxes,
        vars,
    })
}

/// Reads the `LevelData` `spec` of level group `g` holding its components of every box of
/// `boxes`. AMReX's writer stores valid cells only and no attributes group.
fn read_var(g: &Props, spec: &VarSpec, boxes: &[IBox], writer: Writer) -> Result<LevelVar> {
    let (data_name, ncomp) = (&spec.data, spec.comps);
    let ghost = if writer == Writer::AmrexHdf5 && !g.has_member(&spec.attributes) {
        [0; 3]
    } else {
        let da = g.child(&spec.attributes)?;
        let v: RawIntVect = da.compound(raw::OUTPUT_GHOST, &raw::INTVECT_MEMBERS)?;
        let gh = [v.intvecti, v.intvectj, v.intvectk].map(i64::from);
        if gh.iter().any(|&x| !(0..=1024).contains(&x)) {
            return Err(da.invalid(format!("outputGhost = {gh:?}, expected 0 to 1024")));
        }
        if da.has(raw::COMPS) {
            let c = da.int(raw::COMPS)?;
            if c != ncomp as i64 {
                return Err(da.invalid(format!(
                    "comps = {c}, but {ncomp} components are expected (num_components at the \
                     root, or level_0's comps)"
                )));
            }
        }
        gh
    };
    let mut var = LevelVar {
        ncomp,
        ghost,
        offsets: vec![0],
        precision: Precision::F64,
        data: None,
    };
    if boxes.is_empty() && !g.has_member(data_name) {
        return Ok(var);
    }
    let data = g.dataset(data_name)?;
    var.precision = match data.dtype().and_then(|t| t.to_descriptor()) {
        Ok(TypeDescriptor::Float(FloatSize::U4)) => Precision::F32,
        Ok(TypeDescriptor::Float(FloatSize::U8)) => Precision::F64,
        Ok(d) => {
            return Err(g.unsupported(format!(
                "{data_name}: values of type {d}; only 32- and 64-bit floats are supported"
            )))
        }
        Err(e) => return Err(g.hdf5(format!("reading the type of {}/{data_name}", g.name()), e)),
    };
    let shape = data.shape();
    if shape.len() != 1 {
        return Err(g.invalid(format!(
            "{data_name} has shape {shape:?}, expected one dimension"
        )));
    }
    let len = shape[0] as u64;
    var.offsets = read_offsets(g, spec, &var, boxes, len)?;
    // A dataset's declared length costs nothing on disk; its stored bytes do. Unfiltered data
    // must be stored in full, which bounds everything sized from the boxes by the file's size.
    let need = var.offsets[boxes.len()].saturating_mul(var.precision.bytes());
    let stored = data.storage_size();
    if data.filters().is_empty() && stored < need {
        return Err(g.invalid(format!(
            "{data_name} stores {stored} bytes, but its offsets need {need}: the data was never \
             written or the file is damaged"
        )));
    }
    var.data = Some(data);
    Ok(var)
}

/// Reads `boxes`, checking each is non-empty and inside the domain. A box takes at least a
/// byte of the file, which bounds what a corrupt count can make us allocate.
fn read_boxes(g: &Props, domain: &IBox, file_len: u64) -> Result<Vec<IBox>> {
    let ds = g.dataset(raw::BOXES)?;
    if ds.size() as u64 > file_len {
        return Err(g.invalid(format!(
            "{} claims {} boxes, more than the file has bytes ({file_len})",
            raw::BOXES,
            ds.size()
        )));
    }
    let what = || format!("reading {}/{}", g.name(), raw::BOXES);
    let desc = ds
        .dtype()
        .and_then(|t| t.to_descriptor())
        .map_err(|e| g.hdf5(what(), e))?;
    check_members(&desc, &raw::BOX_MEMBERS)
        .map_err(|m| g.invalid(format!("{}: {m}", raw::BOXES)))?;
    if ds.ndim() > 1 {
        return Err(g.invalid(format!(
            "{} has shape {:?}, expected one dimension",
            raw::BOXES,
            ds.shape()
        )));
    }
    let raw_boxes = ds.read_raw::<RawBox>().map_err(|e| g.hdf5(what(), e))?;
    raw_boxes
        .into_iter()
        .enumerate()
        .map(|(i, rb)| {
            let b = to_ibox(rb);
            if b.is_empty() {
                return Err(g.invalid(format!("box {i} {} is empty", show(&b))));
            }
            if !domain.contains_box(&b) {
                return Err(g.invalid(format!(
                    "box {i} {} lies outside the problem domain {}",
                    show(&b),
                    show(domain)
                )));
            }
            Ok(b)
        })
        .collect()
}

/// Reads `spec`'s offsets and checks them against the boxes and the data's length `len`.
fn read_offsets(
    g: &Props,
    spec: &VarSpec,
    var: &LevelVar,
    boxes: &[IBox],
    len: u64,
) -> Result<Vec<u64>> {
    let (offsets_name, data_name) = (&spec.offsets, &spec.data);
    let ncomp = var.ncomp;
    let ds = g.dataset(offsets_name)?;
    let what = || format!("reading {}/{offsets_name}", g.name());
    let desc = ds
        .dtype()
        .and_then(|t| t.to_descriptor())
        .map_err(|e| g.hdf5(what(), e))?;
    if !matches!(
        desc,
        TypeDescriptor::Integer(_) | TypeDescriptor::Unsigned(_)
    ) {
        return Err(g.invalid(format!(
            "{} has type {desc}, expected integers",
            offsets_name
        )));
    }
    let nb = boxes.len();
    if ds.size() != nb + 1 {
        return Err(g.invalid(format!(
            "{} has {} entries, expected {} (boxes + 1)",
            offsets_name,
            ds.size(),
            nb + 1
        )));
    }
    let offsets = ds.read_raw::<i64>().map_err(|e| g.hdf5(what(), e))?;
    if offsets.len() != nb + 1 {
        return Err(g.invalid(format!(
            "{} has {} entries, expected {} (boxes + 1)",
            offsets_name,
            offsets.len(),
            nb + 1
        )));
    }
    let mut out = Vec::with_capacity(nb + 1);
    for (i, w) in offsets.windows(2).enumerate() {
        let stored = var.stored_box(&boxes[i]);
        let need = stored
            .num_cells()
            .and_then(|c| c.checked_mul(ncomp as u64))
            .ok_or_else(|| g.invalid(format!("box {i} {} is too large", show(&boxes[i]))))?;
        if w[0] < 0 || w[1] < w[0] || (w[1] - w[0]) as u64 != need {
            return Err(g.invalid(format!(
                "{} gives box {i} {} the values {}..{}, but {ncomp} components of {} cells (ghost layers {:?} included) need {need}",
                offsets_name,
                show(&boxes[i]),
                w[0],
                w[1],
                stored.num_cells().unwrap_or(0),
                var.ghost
            )));
        }
        out.push(w[0] as u64);
    }
    let last = offsets[nb];
    if last < 0 || last as u64 > len {
        return Err(g.invalid(format!(
            "{} reaches value {last}, beyond the end of {} ({len} values)",
            offsets_name, data_name
        )));
    }
    out.push(last as u64);
    Ok(out)
}

/// Checks that level `l` refines level `l - 1` as its ratio and cell size say.
fn check_refinement(g: &Props, l: usize, coarse: &Level, fine: &Level) -> Result<()> {
    let r = coarse.ref_ratio.map(i64::from);
    if coarse.domain.refine(r) != Some(fine.domain) {
        return Err(g.invalid(format!(
            "prob_domain {} is not level_{} prob_domain {} refined by ref_ratio {:?}",
            show(&fine.domain),
            l - 1,
            show(&coarse.domain),
            coarse.ref_ratio
        )));
    }
    for a in 0..3 {
        let expect = coarse.dx[a] / r[a] as f64;
        if ((fine.dx[a] - expect) / expect).abs() > 1e-6 {
            return Err(g.invalid(format!(
                "dx = {:?} is not level_{} dx {:?} divided by ref_ratio {:?}",
                fine.dx,
                l - 1,
                coarse.dx,
                coarse.ref_ratio
            )));
        }
    }
    Ok(())
}

/// The refinement ratio of `coarse` to `fine` (level `l`) per axis, from their domains, in an
/// AMReX HDF5 plotfile, whose `ref_ratio` holds only the x ratio (checked against it): each
/// axis's must divide exactly and be at least 2, as `.amrk` requires.
fn ratio_of_domains(g: &Props, l: usize, coarse: &Level, fine: &Level) -> Result<[u32; 3]> {
    let (c, f) = (coarse.domain.extent(), fine.domain.extent());
    let mut ratio = [0u32; 3];
    for a in 0..3 {
        let r = f[a] / c[a];
        if f[a] % c[a] != 0 || !(2..=1024).contains(&r) {
            return Err(g.invalid(format!(
                "prob_domain {} is not level_{} prob_domain {} refined by a whole ratio of 2 to \
                 1024 on axis {a} (a ratio of 1, as quasi-2D runs use, cannot be stored: \
                 docs/format.md, \"Why every ratio is at least 2\")",
                show(&fine.domain),
                l - 1,
                show(&coarse.domain)
            )));
        }
        ratio[a] = r as u32;
    }
    if ratio[0] != coarse.ref_ratio[0] {
        return Err(g.invalid(format!(
            "level_{} ref_ratio = {}, but the domains refine x by {}",
            l - 1,
            coarse.ref_ratio[0],
            ratio[0]
        )));
    }
    Ok(ratio)
}

/// A Chombo box (inclusive corners) as a half-open [`IBox`].
fn to_ibox(b: RawBox) -> IBox {
    IBox::new(
        [b.lo_i, b.lo_j, b.lo_k].map(i64::from),
        [b.hi_i, b.hi_j, b.hi_k].map(|h| i64::from(h) + 1),
    )
}

/// A half-open box in Chombo's inclusive notation, for messages.
pub(crate) fn show(b: &IBox) -> String {
    format!("{:?}..={:?}", b.lo, b.hi.map(|h| h - 1))
}

//! How a scene is looked at: the camera, the image size and sampling, the lighting and the
//! normals. A [`View`] holds no data of the scene: changing it costs one frame, no extraction.

use crate::camera::{Camera, CameraError, ViewFrom};
use crate::coloring::ColorScale;
use crate::error::{RenderError, Result};
use crate::frustum::Frustum;
use crate::outline::Outline;
use crate::output::background::Background;
use crate::sample_mode::SampleStep;
use crate::shade::{IsoSpec, Lighting, RenderSettings};
use crate::trace::{GridFrame, VoxelSource};

/// Most samples per pixel a view may ask for.
pub const MAX_SPP: u32 = 4096;
/// Most pixels of an image.
pub const MAX_PIXELS: u64 = 1 << 28;
/// Most steps per domain diagonal the sample method may take per ray.
pub const MAX_STEPS_PER_DIAGONAL: f64 = 1e6;

/// A camera placed by the user: position, and optionally the point looked at (default: the
/// domain's centre) and the up vector (default: z, or y when the view is along z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraPlacement {
    /// Camera position, world coordinates.
    pub pos: [f64; 3],
    /// Point looked at, world coordinates.
    pub look_at: Option<[f64; 3]>,
    /// Up vector.
    pub up: Option<[f64; 3]>,
}

/// Everything a frame needs besides the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// The camera; `None` frames the domain automatically.
    pub camera: Option<CameraPlacement>,
    /// Where the automatic camera looks from (`None`: from above the front right, framing
    /// the sphere around the box); unused when `camera` is set.
    pub view_from: Option<ViewFrom>,
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
    /// Orthographic projection (parallel rays) instead of perspective.
    pub orthographic: bool,
    /// The orthographic picture's height, world units; `None`: as tall as the perspective
    /// picture is at the point looked at ([`Camera::orthographic`]), and for the automatic
    /// camera, what fits what it frames ([`Camera::orthographic_framing`];
    /// [`View::keep_height_of`] keeps it for the frames placed from it).
    pub view_height: Option<f64>,
    /// Width and height in pixels.
    pub size: (u32, u32),
    /// Samples per pixel.
    pub spp: u32,
    /// Cast shadow rays from the key light.
    pub shadows: bool,
    /// Ambient-occlusion rays per hit (0 disables).
    pub ao_rays: u32,
    /// Filter the ambient occlusion across neighbouring pixels of the same surface (frames of
    /// one sample per pixel; [`crate::shade::ao_filter`]).
    pub ao_filter: bool,
    /// Normals continuous across voxels (central differences of the reconstruction) instead of
    /// each voxel's own trilinear gradient.
    pub smooth_normals: bool,
    /// Step of the sample method along rays, world units; `None` is half a cell of the level
    /// each sample lands in.
    pub sample_step: Option<f64>,
    /// How the values that paint surfaces and slices become colours.
    pub color_scale: ColorScale,
    /// Fields painted with a scale of their own instead of `color_scale`, by name.
    pub field_scales: Vec<(String, ColorScale)>,
    /// The boxes drawn as lines (scene frames only).
    pub outline: Outline,
    /// What a picture of the frame shows where no surface is, and what its lines and labels
    /// stand out from.
    pub background: Background,
}

impl Default for View {
    fn default() -> View {
        View {
            camera: None,
            view_from: None,
            fov_deg: 40.0,
            orthographic: false,
            view_height: None,
            size: (1024, 768),
            spp: 1,
            shadows: true,
            ao_rays: 1,
            ao_filter: true,
            smooth_normals: true,
            sample_step: None,
            color_scale: ColorScale::default(),
            field_scales: Vec::new(),
            outline: Outline::None,
            background: Background::default(),
        }
    }
}

impl View {
    /// Checks everything that can be checked without a scene.
    pub fn validate(&self) -> Result<()> {
        let (w, h) = self.size;
        if w == 0 || h == 0 || u64::from(w) * u64::from(h) > MAX_PIXELS {
            return Err(RenderError::Invalid(format!(
                "image size {w}x{h} must be at least 1x1 and at most 2^28 pixels"
            )));
        }
        if !(self.fov_deg > 0.0 && self.fov_deg < 180.0) {
            return Err(CameraError::BadFov(self.fov_deg).into());
        }
        if let Some(height) = self.view_height {
            if !self.orthographic {
                return Err(RenderError::Invalid(format!(
                    "a view height ({height}) is for an orthographic view: add --ortho"
                )));
            }
            if !(height > 0.0 && height.is_finite()) {
                return Err(CameraError::BadViewHeight(height).into());
            }
        }
        if !(1..=MAX_SPP).contains(&self.spp) {
            return Err(RenderError::Invalid(format!(
                "samples per pixel {} must be between 1 and {MAX_SPP}",
                self.spp
            )));
        }
        if self.ao_rays > MAX_SPP {
            return Err(RenderError::Invalid(format!(
                "ambient-occlusion rays {} must be at most {MAX_SPP}",
                self.ao_rays
            )));
        }
        if let Some(s) = self.sample_step {
            if !(s > 0.0 && s.is_finite()) {
                return Err(RenderError::Invalid(format!(
                    "sample step {s} must be positive and finite"
                )));
            }
        }
        self.color_scale.validate().map_err(RenderError::Invalid)?;
        for (field, scale) in &self.field_scales {
            scale
                .validate()
                .map_err(|e| RenderError::Invalid(format!("{field}: {e}")))?;
        }
        if let Some(from) = &self.view_from {
            // The unit box: the direction and up vector are checked whatever box is framed.
            Camera::framing_from([0.0; 3], [1.0; 3], from, self.fov_deg, 1.0)?;
        }
        if let Some(CameraPlacement {
            pos,
            look_at: Some(look),
            up,
        }) = self.camera
        {
            self.projected(placed_camera(pos, look, up, self.fov_deg)?)?;
        }
        Ok(())
    }

    /// The camera for a domain with grid frame `frame`.
    pub fn camera(&self, frame: &GridFrame) -> Result<Camera> {
        let (lo, hi) = frame.world_bounds();
        let centre = [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a]));
        match self.camera {
            Some(c) => {
                let placed = placed_camera(c.pos, c.look_at.unwrap_or(centre), c.up, self.fov_deg)?;
                self.projected(placed)
            }
            None => self.auto_camera(lo, hi),
        }
    }

    /// `camera` (perspective) with this view's projection.
    fn projected(&self, camera: Camera) -> Result<Camera> {
        match self.orthographic {
            true => Ok(camera.orthographic(self.view_height)?),
            false => Ok(camera),
        }
    }

    /// The automatic camera that frames the world box `[lo, hi]`.
    fn auto_camera(&self, lo: [f64; 3], hi: [f64; 3]) -> Result<Camera> {
        let (w, h) = self.size;
        let aspect = f64::from(w) / f64::from(h);
        let (camera, tight) = match &self.view_from {
            Some(from) => (
                Camera::framing_from(lo, hi, from, self.fov_deg, aspect)?,
                from.tight,
            ),
            None => (Camera::framing(lo, hi, self.fov_deg, aspect)?, false),
        };
        match self.orthographic {
            true => Ok(camera.orthographic_framing((lo, hi), aspect, tight, self.view_height)?),
            false => Ok(camera),
        }
    }

    /// The frustum of this view's primary rays in a domain with grid frame `frame`.
    pub fn frustum(&self, frame: &GridFrame) -> Result<Frustum> {
        Ok(Frustum::of_camera(&self.camera(frame)?, self.size, frame))
    }

    /// This view with its camera placed as the automatic camera frames the world box
    /// `[lo, hi]` (for a view of the surfaces rather than of the whole domain).
    pub fn framing(&self, (lo, hi): ([f64; 3], [f64; 3])) -> Result<View> {
        let c = self.auto_camera(lo, hi)?;
        let mut view = self.clone();
        view.camera = Some(CameraPlacement {
            pos: c.pos,
            look_at: Some(c.look_at),
            up: Some(c.up),
        });
        view.keep_height_of(&c);
        Ok(view)
    }

    /// An orthographic view without a height of its own takes `camera`'s (the automatic
    /// camera's, which fits what it frames whatever the field of view), so that the frames of
    /// an orbit or a series, placed from it, show the scale it framed. Nothing otherwise.
    pub fn keep_height_of(&mut self, camera: &Camera) {
        if self.orthographic && self.view_height.is_none() {
            self.view_height = camera.projection_height();
        }
    }

    /// The lighting of `isos` seen by `camera` in a domain with grid frame `frame`.
    pub fn lighting(&self, camera: &Camera, frame: &GridFrame, isos: &[IsoSpec]) -> Lighting {
        let (lo, hi) = frame.world_bounds();
        let diag = (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
        let colors = isos
            .iter()
            .enumerate()
            .map(|(i, s)| s.color_or_palette(i))
            .collect();
        let opacity = isos.iter().map(|s| s.opacity).collect();
        let mut light = Lighting::for_camera(camera, colors, opacity, 0.08 * diag);
        light.shadows = self.shadows;
        light.ao_rays = self.ao_rays;
        light.ao_filter = self.ao_filter;
        light
    }

    /// Image size and sampling.
    pub fn settings(&self) -> RenderSettings {
        RenderSettings {
            width: self.size.0,
            height: self.size.1,
            spp: self.spp,
        }
    }

    /// The step of the sample method through `src`: the view's, or half a cell of the level
    /// each sample lands in (half a grid unit, a quarter of a finest cell, for a source without
    /// levels); a step given in the view is refused when a ray would take more than
    /// [`MAX_STEPS_PER_DIAGONAL`] steps across the domain.
    pub fn sample_step<S: VoxelSource + ?Sized>(&self, src: &S) -> Result<SampleStep> {
        let frame = src.frame();
        let Some(step) = self.sample_step else {
            return Ok(match SampleStep::half_cells(src) {
                SampleStep::PerLevel(steps) if steps.is_empty() => {
                    SampleStep::Fixed(0.5 * frame.unit.iter().fold(f64::INFINITY, |m, &u| m.min(u)))
                }
                per_level => per_level,
            });
        };
        let (lo, hi) = frame.world_bounds();
        let diag = (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt();
        if !(step > 0.0 && step.is_finite()) {
            return Err(RenderError::Invalid(format!(
                "sample step {step} must be positive and finite"
            )));
        }
        if diag / step > MAX_STEPS_PER_DIAGONAL {
            return Err(RenderError::Invalid(format!(
                "sample step {step} would take {:.3e} steps across the domain (diagonal {diag:.6e}); \
                 the limit is {MAX_STEPS_PER_DIAGONAL:.0e}",
                diag / step
            )));
        }
        Ok(SampleStep::Fixed(step))
    }
}

/// A camera from user input: `up` defaults to z, or y when the view is along z.
fn placed_camera(
    pos: [f64; 3],
    look: [f64; 3],
    up: Option<[f64; 3]>,
    fov: f64,
) -> Result<Camera, CameraError> {
    match up {
        Some(up) => Camera::new(pos, look, up, fov),
        None => Camera::new(pos, look, [0.0, 0.0, 1.0], fov).or_else(|e| match e {
            CameraError::BadUp(_) => Camera::new(pos, look, [0.0, 1.0, 0.0], fov),
            e => Err(e),
        }),
    }
}

//! What changes from frame to frame of one run: the file (a time series), the camera (an orbit
//! or keyframes) and one isovalue (a sweep). Whatever is given animates in lockstep, so the
//! counts must agree.

use std::path::Path;
use std::str::FromStr;

use amr_render::camera::Camera;
use amr_render::camera_path::{interpolate, orbit, CameraKey};
use amr_render::field_stats::percentile_values;
use amr_render::mapping::MappedFile;
use amr_render::shade::IsoSpec;
use amr_render::CameraPlacement;
use anyhow::bail;

use crate::iso_value::IsoValue;
use crate::surface_arg::split_field;

/// Most frames one run renders.
pub const MAX_FRAMES: u32 = 100_000;

/// An isosurface whose value goes from `from` to `to` over `frames` frames.
#[derive(Clone, Debug, PartialEq)]
pub struct IsoSweep {
    /// The swept surface's colour and opacity (its value that of the first frame when typed as
    /// a number).
    pub first: IsoSpec,
    /// The first frame's isovalue, as typed.
    pub from: IsoValue,
    /// The last frame's isovalue, as typed.
    pub to: IsoValue,
    /// Frames.
    pub frames: u32,
    /// The field swept, when not `--field`'s: its name, resolved in each file.
    pub field: Option<String>,
}

/// A sweep's surface in one file: its field's index there (`None`: the scene's field) and the
/// isovalue of every frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SweptSurface {
    /// The field's index in the file.
    pub field: Option<usize>,
    /// The isovalue of each frame.
    pub values: Vec<f32>,
}

impl IsoSweep {
    /// The fraction of the way frame `k` lies, 0 at the first frame and 1 at the last.
    fn step(&self, k: u32) -> f64 {
        match self.frames > 1 {
            true => f64::from(k) / f64::from(self.frames - 1),
            false => 0.0,
        }
    }

    /// The isovalue of every frame in field `field` of `file` (opened from `path`): evenly
    /// spaced from `from` to `to`, both included; between two percentiles, evenly spaced
    /// percentiles (each frame a like share of the cells further in: the steps a field spanning
    /// decades needs), each rounded as a single `--iso pQ` is; between a number and a
    /// percentile, values evenly spaced from the number to that percentile's value.
    pub fn values(&self, file: &MappedFile, path: &Path, field: usize) -> anyhow::Result<Vec<f32>> {
        let frames = 0..self.frames;
        if let (IsoValue::Percentile(a), IsoValue::Percentile(b)) = (self.from, self.to) {
            let percents: Vec<f64> = frames.map(|k| a + (b - a) * self.step(k)).collect();
            return percentile_values(file, field, &percents).map_err(|e| e.in_file(path).into());
        }
        let a = f64::from(self.from.resolve(file, path, field)?);
        let b = f64::from(self.to.resolve(file, path, field)?);
        Ok(frames
            .map(|k| (a + (b - a) * self.step(k)) as f32)
            .collect())
    }
}

impl FromStr for IsoSweep {
    type Err = String;

    /// `[FIELD=]A:B:N[:COLOR[:OPACITY]]`, `A` and `B` numbers or percentiles (`p50:p99.9:20`).
    fn from_str(text: &str) -> Result<Self, String> {
        let (field, s) = split_field(text)?;
        let parts: Vec<&str> = s.splitn(4, ':').collect();
        if parts.len() < 3 {
            return Err(format!("sweep '{s}' is not A:B:N[:COLOR[:OPACITY]]"));
        }
        let from: IsoValue = parts[0].parse()?;
        let to: IsoValue = parts[1].parse()?;
        let frames: u32 = parts[2]
            .trim()
            .parse()
            .map_err(|_| format!("'{}' in '{s}' is not a frame count", parts[2]))?;
        if !(1..=MAX_FRAMES).contains(&frames) {
            return Err(format!("sweep of {frames} frames: give 1 to {MAX_FRAMES}"));
        }
        let number = from.typed_number();
        let first = match parts.get(3) {
            Some(rest) => format!("{number}:{rest}"),
            None => number.to_string(),
        };
        Ok(IsoSweep {
            first: first.parse()?,
            from,
            to,
            frames,
            field,
        })
    }
}

/// The frames of one run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Animation {
    /// Number of frames.
    pub frames: u32,
    /// Files of a time series (more than one), one per frame.
    pub series: bool,
    /// Frames of an orbit and the degrees it turns.
    pub orbit: Option<(u32, f64)>,
    /// An isovalue sweep.
    pub sweep: Option<IsoSweep>,
    /// Camera keyframes.
    pub keyframes: Vec<CameraKey>,
}

impl Animation {
    /// The frames of a run over `files` files with an optional orbit, sweep and keyframes.
    pub fn new(
        files: usize,
        orbit: Option<(u32, f64)>,
        sweep: Option<IsoSweep>,
        mut keyframes: Vec<CameraKey>,
    ) -> anyhow::Result<Animation> {
        keyframes.sort_by_key(|k| k.frame);
        if let Some(w) = keyframes.windows(2).find(|w| w[0].frame == w[1].frame) {
            bail!("two --keyframe options name frame {}", w[0].frame);
        }
        if orbit.is_some() && !keyframes.is_empty() {
            bail!("--orbit and --keyframe are two camera paths: give one");
        }
        if let Some((n, degrees)) = orbit {
            if !(1..=MAX_FRAMES).contains(&n) || !degrees.is_finite() {
                bail!("--orbit {n} --orbit-degrees {degrees}: give 1 to {MAX_FRAMES} frames and a finite angle");
            }
        }
        let mut counts: Vec<(String, u32)> = Vec::new();
        if files > 1 {
            let n = u32::try_from(files).unwrap_or(u32::MAX);
            counts.push((format!("{files} files"), n));
        }
        if let Some((n, _)) = orbit {
            counts.push((format!("--orbit {n}"), n));
        }
        if let Some(s) = &sweep {
            counts.push((format!("--iso-sweep of {} frames", s.frames), s.frames));
        }
        if let Some((a, b)) = counts
            .iter()
            .zip(counts.iter().skip(1))
            .find(|(a, b)| a.1 != b.1)
        {
            bail!(
                "{} and {}: an animation's parts run in lockstep, so their frame counts must agree",
                a.0,
                b.0
            );
        }
        let from_keys = keyframes.last().map_or(1, |k| k.frame.saturating_add(1));
        let frames = counts.first().map_or(from_keys, |c| c.1);
        if frames > MAX_FRAMES {
            bail!("{frames} frames: one run renders at most {MAX_FRAMES}");
        }
        Ok(Animation {
            frames,
            series: files > 1,
            orbit,
            sweep,
            keyframes,
        })
    }

    /// The camera of every frame: along the orbit or the keyframes, else `start` (the first
    /// frame's camera, kept for a time series so that its frames compare).
    pub fn cameras(&self, start: &Camera) -> anyhow::Result<Vec<CameraPlacement>> {
        if let Some((n, degrees)) = self.orbit {
            return Ok(orbit(start, n, degrees)?);
        }
        if !self.keyframes.is_empty() {
            return (0..self.frames)
                .map(|k| Ok(interpolate(&self.keyframes, k)?))
                .collect();
        }
        let fixed = CameraPlacement {
            pos: start.pos,
            look_at: Some(start.look_at),
            up: Some(start.up),
        };
        Ok(vec![fixed; self.frames as usize])
    }

    /// The isosurfaces of frame `k`: `isos` and the sweep's surface of that frame, `swept` in
    /// the frame's file.
    pub fn isos(&self, isos: &[IsoSpec], k: u32, swept: Option<&SweptSurface>) -> Vec<IsoSpec> {
        let mut all = isos.to_vec();
        if let (Some(s), Some(swept)) = (&self.sweep, swept) {
            all.push(IsoSpec {
                field: swept.field,
                value: swept
                    .values
                    .get(k as usize)
                    .copied()
                    .unwrap_or(s.first.value),
                ..s.first
            });
        }
        all
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sweep_of_another_field_names_it_and_gives_its_index_to_its_surfaces() {
        let s: IsoSweep = "Y(OH)=1e-4:5e-4:3:red".parse().unwrap();
        assert_eq!(s.field.as_deref(), Some("Y(OH)"));
        assert_eq!(
            (s.from, s.to, s.frames),
            (IsoValue::Number(1e-4), IsoValue::Number(5e-4), 3)
        );
        let anim = Animation::new(1, None, Some(s), vec![]).unwrap();
        let swept = SweptSurface {
            field: Some(7),
            values: vec![1e-4, 3e-4, 5e-4],
        };
        let isos = anim.isos(&[IsoSpec::new(2.0)], 2, Some(&swept));
        assert_eq!(isos.len(), 2);
        assert_eq!(
            (isos[0].field, isos[1].field, isos[1].value),
            (None, Some(7), 5e-4)
        );
        assert!("=1:2:3".parse::<IsoSweep>().is_err());
        let p: IsoSweep = "p50:P99.9:20:gold:0.5".parse().unwrap();
        assert_eq!(
            (p.from, p.to, p.first.opacity),
            (IsoValue::Percentile(50.0), IsoValue::Percentile(99.9), 0.5)
        );
        assert!("p50:p101:20".parse::<IsoSweep>().is_err());
    }

    #[test]
    fn a_sweep_includes_both_ends() {
        let s: IsoSweep = "-1:1:5:red:0.5".parse().unwrap();
        let v: Vec<f64> = (0..5).map(|k| -1.0 + 2.0 * s.step(k)).collect();
        assert_eq!(v, [-1.0, -0.5, 0.0, 0.5, 1.0]);
        assert_eq!(s.first.opacity, 0.5);
        assert!("1:2".parse::<IsoSweep>().is_err());
        assert!("1:2:0".parse::<IsoSweep>().is_err());
    }

    #[test]
    fn counts_must_agree() {
        let sweep: IsoSweep = "0:1:4".parse().unwrap();
        assert_eq!(
            Animation::new(4, Some((4, 360.0)), Some(sweep), vec![])
                .unwrap()
                .frames,
            4
        );
        assert!(Animation::new(3, Some((4, 360.0)), None, vec![]).is_err());
        assert_eq!(Animation::new(1, None, None, vec![]).unwrap().frames, 1);
        let key = CameraKey {
            frame: 9,
            pos: [1.0; 3],
            look_at: [0.0; 3],
            up: [0.0, 0.0, 1.0],
        };
        assert_eq!(Animation::new(1, None, None, vec![key]).unwrap().frames, 10);
        assert!(Animation::new(1, Some((4, 90.0)), None, vec![key]).is_err());
    }
}

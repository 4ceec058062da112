//! The frame loop traces the shadow and ambient-occlusion rays of every layer of a tile as
//! packets (`KeyShadow`, `TileAo`: the AO rays layer by layer, each pixel's pattern drawn in
//! layer order); every pixel is the one the single-ray shader ([`shade_ray`]) gives it: the
//! same AO rays, the pixel's random pattern moved on the same way for the hits behind, the same
//! sums. Checked on frames of an opaque surface behind a transparent one (so the second
//! layer's AO rays are packets too), close and far, with the per-pixel AO pattern (one sample
//! per pixel) and the pattern spread over tiles (two samples per pixel, so that the cross-pixel
//! filter stays off and pixels compare one by one).

use amr_render::camera::Camera;
use amr_render::output::frame::{FrameBuffer, PixelSample};
use amr_render::shade::integrate::SearchHint;
use amr_render::shade::sampling::Rng;
use amr_render::shade::{render_frame, shade_ray, IsoSpec, Lighting, RenderSettings};
use amr_render::trace::HybridTracer;
use amr_render::Scene;
use amr_render::SceneOptions;
use amr_synth::Case;

use crate::support::synth_file::two_level;

/// Pixel `(x, y)` of `frame`'s colour and coverage.
fn rgba(frame: &FrameBuffer, x: u32, y: u32) -> [f32; 4] {
    let i = (y * frame.width + x) as usize;
    [
        frame.rgb[0][i],
        frame.rgb[1][i],
        frame.rgb[2][i],
        frame.alpha[i],
    ]
}

/// The pixel the single-ray shader gives, its `spp` samples averaged as the frame loop does.
fn single_ray_pixel(
    tracer: &HybridTracer<'_, impl amr_render::trace::VoxelSource + ?Sized>,
    camera: &Camera,
    light: &Lighting,
    (w, h, spp): (u32, u32, u32),
    (x, y): (u32, u32),
) -> [f32; 4] {
    let dirs = camera.pixel_dirs(w, h);
    let mut sum = [0.0f32; 4];
    for s in 0..spp {
        let mut rng = Rng::for_pixel(x, y, s);
        let (jx, jy) = rng.subpixel(spp);
        let ray = dirs.ray(f64::from(x) + jx, f64::from(y) + jy);
        let mut hint = SearchHint::default();
        let p: PixelSample = shade_ray(tracer, light, ray, &mut rng, &mut hint, None);
        for c in 0..3 {
            sum[c] += p.rgb[c];
        }
        sum[3] += p.alpha;
    }
    let inv = 1.0 / spp as f32;
    sum.map(|v| v * inv)
}

#[test]
fn layer_packets_shade_every_pixel_as_single_rays_do() {
    let dir = tempfile::tempdir().unwrap();
    let path = two_level(dir.path(), Case::Blobs);
    let mut scene = Scene::open(&path, &SceneOptions::default()).unwrap();
    let shell = IsoSpec {
        opacity: 0.3,
        ..IsoSpec::new(6.0)
    };
    scene.set_isosurfaces(&[IsoSpec::new(10.0), shell]).unwrap();
    let tracer = HybridTracer {
        src: scene.source(),
        surfaces: scene.surfaces(),
        sources: &[],
        smooth_normals: true,
    };
    // A close view and a far one (hits of a tile close together, and far apart).
    let cameras = [
        Camera::new([0.8, 0.7, 1.1], [0.5, 0.5, 0.5], [0.0, 1.0, 0.0], 25.0).unwrap(),
        Camera::new([2.5, 2.0, 3.5], [0.5, 0.5, 0.5], [0.0, 1.0, 0.0], 30.0).unwrap(),
    ];
    let (w, h) = (72, 56);
    let mut compared = 0;
    for camera in &cameras {
        for (ao_rays, ao_filter, spp) in [(2, false, 1), (1, true, 2), (3, true, 2)] {
            let mut light = Lighting::for_camera(
                camera,
                vec![[0.8, 0.6, 0.3], [0.3, 0.5, 0.8]],
                vec![1.0, 0.3],
                0.15,
            );
            light.ao_rays = ao_rays;
            light.ao_filter = ao_filter;
            let settings = RenderSettings {
                width: w,
                height: h,
                spp,
            };
            let (frame, _) = render_frame(&tracer, camera, &light, settings, &|_| {});
            for y in 0..h {
                for x in 0..w {
                    let want = single_ray_pixel(&tracer, camera, &light, (w, h, spp), (x, y));
                    let got = rgba(&frame, x, y);
                    assert_eq!(
                        got.map(f32::to_bits),
                        want.map(f32::to_bits),
                        "pixel ({x}, {y}), {ao_rays} AO rays, filter {ao_filter}, spp {spp}: \
                         {got:?} != {want:?}"
                    );
                    compared += usize::from(want[3] > 0.0);
                }
            }
        }
    }
    assert!(compared > 5000, "only {compared} pixels hit");
}

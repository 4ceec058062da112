//! Shading like a scientific-visualization renderer: headlight diffuse and specular, a key
//! light with hard shadows, ambient occlusion, per-isosurface colour and opacity, and
//! transparent surfaces composited front to back.

pub mod ao_filter;
pub mod ao_packets;
pub mod integrate;
pub mod layers;
pub mod material;
pub mod packets;
pub mod render_loop;
pub mod sampling;

pub use integrate::{shade_ray, Lighting};
pub use material::IsoSpec;
pub use render_loop::{render_frame, render_in_planes, render_rect, RenderSettings};

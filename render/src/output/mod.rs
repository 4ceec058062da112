//! Writing frames: OpenEXR with every channel and the render's metadata, and a PNG preview.

mod axes;
pub mod background;
mod canvas;
pub mod exr_file;
pub mod frame;
pub mod header;
pub mod legend;
pub mod png_preview;

pub use background::Background;
pub use frame::{FrameBuffer, PixelSample};

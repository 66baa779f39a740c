//! The finished picture and how it reaches the disk.

pub mod assemble;
pub mod bmp;
pub mod framebuffer;
pub mod tile;
pub mod write;

pub use framebuffer::Framebuffer;
pub use write::{
    OutputError, check_output, check_output_dir, is_png, next_free_output, remove_temporaries,
    same_file, write_atomic, write_image, write_image_no_clobber, write_next_output, write_tile,
};

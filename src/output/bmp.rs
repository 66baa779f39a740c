//! BMP encoding, rows in parallel.
//!
//! The `image` crate's BMP encoder writes pixel by pixel into one writer, serially
//! after a parallel render. A BMP is a fixed 54-byte header and independent rows, so
//! rows are encoded on the render's thread pool. Decoded by the `image` crate's reader
//! in `tests`, pixel for pixel.

use rayon::prelude::*;

use super::Framebuffer;

/// Bytes of the file and info headers (BITMAPFILEHEADER + BITMAPINFOHEADER).
const HEADER: usize = 14 + 40;

/// The 24-bit, bottom-up, uncompressed BMP of `fb`.
pub fn encode(fb: &Framebuffer) -> Vec<u8> {
    let (w, h) = (fb.width as usize, fb.height as usize);
    // each row padded to a multiple of 4 bytes
    let stride = (3 * w).div_ceil(4) * 4;
    let size = HEADER + stride * h;
    let mut out = vec![0u8; size];
    let le32 = |v: usize| (v as u32).to_le_bytes();
    let head = &mut out[..HEADER];
    head[0..2].copy_from_slice(b"BM");
    head[2..6].copy_from_slice(&le32(size));
    head[10..14].copy_from_slice(&le32(HEADER)); // pixel data offset
    head[14..18].copy_from_slice(&le32(40)); // info header size
    head[18..22].copy_from_slice(&le32(w));
    head[22..26].copy_from_slice(&le32(h)); // positive: bottom-up rows
    head[26..28].copy_from_slice(&1u16.to_le_bytes()); // planes
    head[28..30].copy_from_slice(&24u16.to_le_bytes()); // bits per pixel
    head[34..38].copy_from_slice(&le32(stride * h)); // image size (no compression)
    head[38..42].copy_from_slice(&le32(2835)); // 72 dpi
    head[42..46].copy_from_slice(&le32(2835));
    if stride > 0 {
        let row = |(i, row): (usize, &mut [u8])| {
            let src = &fb.pixels[(h - 1 - i) * w..(h - i) * w];
            for (dst, p) in row.chunks_exact_mut(3).zip(src) {
                dst.copy_from_slice(&[p[2], p[1], p[0]]);
            }
        };
        if crate::parallel::parallel() {
            out[HEADER..]
                .par_chunks_mut(stride)
                .enumerate()
                .for_each(row);
        } else {
            out[HEADER..].chunks_mut(stride).enumerate().for_each(row);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decodes_to_the_same_pixels_at_every_row_padding() {
        for (w, h) in [(1, 1), (2, 3), (3, 2), (5, 4), (4, 5), (7, 1)] {
            let mut fb = Framebuffer::new(w, h);
            for (i, p) in fb.pixels.iter_mut().enumerate() {
                *p = [(i * 37) as u8, (i * 11 + 5) as u8, (255 - i * 3) as u8];
            }
            let bytes = encode(&fb);
            let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Bmp)
                .unwrap_or_else(|e| panic!("{w}x{h}: {e}"))
                .to_rgb8();
            assert_eq!((img.width(), img.height()), (w, h));
            assert_eq!(img.as_raw().as_slice(), fb.as_bytes(), "{w}x{h}");
        }
    }
}

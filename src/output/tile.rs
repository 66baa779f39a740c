//! Where a piece of a frame belongs, recorded in its PNG file: text chunks (`tEXt`)
//! written before the image data.
//!
//! | keyword | value |
//! |---|---|
//! | `octaray-frame` | the whole frame's size, `WIDTHxHEIGHT` |
//! | `octaray-rect` | the piece's pixels in it, `X0,X1,Y0,Y1` (half-open, as `--crop`); a tile's stripes `;`-separated, stacked top to bottom in the image |
//! | `octaray-tile` | `I/N` when rendered with `--tile I/N` (else absent) |
//! | `octaray-digest` | digest of the scene and every setting that changes pixels |
//! | `octaray-settings` | what the digest covers, readable (several lines) |
//!
//! A whole frame is a piece too (its rectangle is the frame). The digest is computed by
//! the caller ([`crate::farm::digest`]); here it is an opaque string compared for
//! equality.

use std::io::{BufReader, Cursor};
use std::path::Path;

use super::Framebuffer;

/// A piece of a frame: its place and the settings it was rendered with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TileMeta {
    /// The whole frame's size.
    pub frame: (u32, u32),
    /// The piece's pixels: rectangles [x0, x1) × [y0, y1) as `[x0, x1, y0, y1]`, of one
    /// width, stacked top to bottom in the image (one for a crop or a whole frame).
    pub rects: Vec<[u32; 4]>,
    /// `(I, N)` of `--tile I/N`.
    pub tile: Option<(u32, u32)>,
    pub digest: String,
    pub settings: String,
}

impl TileMeta {
    /// The image's width.
    pub fn width(&self) -> u32 {
        self.rects.first().map_or(0, |r| r[1] - r[0])
    }

    /// The image's height: the rectangles' together.
    pub fn height(&self) -> u32 {
        self.rects.iter().map(|r| r[3] - r[2]).sum()
    }

    /// The rectangles as `--crop` takes one, `X0,X1,Y0,Y1`, `;`-separated.
    pub fn rect_text(&self) -> String {
        let texts: Vec<String> = self.rects.iter().map(|r| rect_text(*r)).collect();
        texts.join(";")
    }

    /// The same settings for the whole frame (what an assembled frame records).
    pub fn whole(&self) -> TileMeta {
        TileMeta {
            rects: vec![[0, self.frame.0, 0, self.frame.1]],
            tile: None,
            ..self.clone()
        }
    }

    fn chunks(&self) -> Vec<(&'static str, String)> {
        let mut out = vec![
            (FRAME, format!("{}x{}", self.frame.0, self.frame.1)),
            (RECT, self.rect_text()),
        ];
        if let Some((i, n)) = self.tile {
            out.push((TILE, format!("{i}/{n}")));
        }
        out.push((DIGEST, self.digest.clone()));
        out.push((SETTINGS, self.settings.clone()));
        out
    }
}

const FRAME: &str = "octaray-frame";
const RECT: &str = "octaray-rect";
const TILE: &str = "octaray-tile";
const DIGEST: &str = "octaray-digest";
const SETTINGS: &str = "octaray-settings";

/// Why a file's tile information could not be read.
#[derive(Debug, thiserror::Error)]
pub enum TileError {
    #[error("cannot read: {0}")]
    Io(#[from] std::io::Error),
    #[error(
        "not a readable PNG file ({0}); tiles are written as .png, which records where they belong"
    )]
    NotPng(String),
    #[error(
        "not a tile: no {FRAME} text chunk (write tiles with `octaray render ... -o NAME.png`)"
    )]
    NoMeta,
    #[error("text chunk {key}: {message}, got '{value}'")]
    Bad {
        key: &'static str,
        value: String,
        message: &'static str,
    },
    #[error("the image is {width}x{height}, but its rectangle {rect} is {rw}x{rh}")]
    SizeMismatch {
        width: u32,
        height: u32,
        rect: String,
        rw: u32,
        rh: u32,
    },
    #[error("cannot decode the image: {0}")]
    Decode(String),
}

/// PNG bytes of `fb` (8-bit RGB; the `image` crate's default compression and filter),
/// with `meta` in text chunks.
pub fn encode_png(
    fb: &Framebuffer,
    meta: Option<&TileMeta>,
) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, fb.width, fb.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::Balanced);
    encoder.set_filter(png::Filter::Adaptive);
    encoder.add_text_chunk(
        "Software".into(),
        format!("octaray {}", env!("CARGO_PKG_VERSION")),
    )?;
    for (key, value) in meta.map(TileMeta::chunks).unwrap_or_default() {
        encoder.add_text_chunk(key.into(), value)?;
    }
    let mut writer = encoder.write_header()?;
    writer.write_image_data(fb.as_bytes())?;
    writer.finish()?;
    Ok(out)
}

/// Reads the tile information of a PNG file (its header only, not the pixels).
pub fn read_meta(path: &Path) -> Result<TileMeta, TileError> {
    let file = std::fs::File::open(path)?;
    let reader = png::Decoder::new(BufReader::new(file))
        .read_info()
        .map_err(|e| TileError::NotPng(e.to_string()))?;
    let info = reader.info();
    let text = |key: &str| {
        info.uncompressed_latin1_text
            .iter()
            .find(|c| c.keyword == key)
            .map(|c| c.text.clone())
    };
    let frame_text = text(FRAME).ok_or(TileError::NoMeta)?;
    let bad = |key, value: &str, message| TileError::Bad {
        key,
        value: value.to_string(),
        message,
    };
    let frame = frame_text
        .split_once('x')
        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
        .filter(|&(w, h)| w > 0 && h > 0)
        .ok_or_else(|| bad(FRAME, &frame_text, "expected WIDTHxHEIGHT"))?;
    let rect_text = text(RECT).unwrap_or_default();
    let rects = parse_rects(&rect_text).ok_or_else(|| {
        bad(
            RECT,
            &rect_text,
            "expected X0,X1,Y0,Y1 with X0 < X1, Y0 < Y1 (several, of one width, `;`-separated)",
        )
    })?;
    let tile = match text(TILE) {
        None => None,
        Some(t) => Some(
            t.split_once('/')
                .and_then(|(i, n)| Some((i.parse::<u32>().ok()?, n.parse::<u32>().ok()?)))
                .filter(|&(i, n)| i < n)
                .ok_or_else(|| bad(TILE, &t, "expected I/N with I < N"))?,
        ),
    };
    let digest = text(DIGEST).unwrap_or_default();
    if digest.is_empty() {
        return Err(bad(DIGEST, "", "missing"));
    }
    let meta = TileMeta {
        frame,
        rects,
        tile,
        digest,
        settings: text(SETTINGS).unwrap_or_default(),
    };
    let (w, h) = info.size();
    if (w, h) != (meta.width(), meta.height()) {
        return Err(TileError::SizeMismatch {
            width: w,
            height: h,
            rect: meta.rect_text(),
            rw: meta.width(),
            rh: meta.height(),
        });
    }
    Ok(meta)
}

/// `X0,X1,Y0,Y1`.
pub fn rect_text([x0, x1, y0, y1]: [u32; 4]) -> String {
    format!("{x0},{x1},{y0},{y1}")
}

/// Rectangles of [`parse_rect`], `;`-separated, all of one width.
pub fn parse_rects(s: &str) -> Option<Vec<[u32; 4]>> {
    let rects: Vec<[u32; 4]> = s.split(';').map(parse_rect).collect::<Option<_>>()?;
    let width = rects[0][1] - rects[0][0];
    rects.iter().all(|r| r[1] - r[0] == width).then_some(rects)
}

/// `X0,X1,Y0,Y1` with X0 < X1 and Y0 < Y1.
pub fn parse_rect(s: &str) -> Option<[u32; 4]> {
    let v: Vec<u32> = s
        .split(',')
        .map(|p| p.trim().parse::<u32>().ok())
        .collect::<Option<_>>()?;
    let [x0, x1, y0, y1] = v[..] else { return None };
    (x0 < x1 && y0 < y1).then_some([x0, x1, y0, y1])
}

/// Reads the pixels of a PNG file (any bit depth or colour type, as 8-bit RGB).
pub fn read_pixels(path: &Path) -> Result<Framebuffer, TileError> {
    let bytes = std::fs::read(path)?;
    let img = image::load(Cursor::new(bytes), image::ImageFormat::Png)
        .map_err(|e| TileError::Decode(e.to_string()))?
        .to_rgb8();
    let (width, height) = img.dimensions();
    Ok(Framebuffer {
        width,
        height,
        pixels: img.pixels().map(|p| p.0).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta() -> TileMeta {
        TileMeta {
            frame: (7, 5),
            rects: vec![[2, 5, 1, 2], [2, 5, 3, 4]],
            tile: Some((1, 4)),
            digest: "fnv1a128:0123".into(),
            settings: "line one\nline two".into(),
        }
    }

    fn dir(tag: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("octaray-tile-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn metadata_and_pixels_round_trip() {
        let d = dir("round");
        let mut fb = Framebuffer::new(3, 2);
        fb.pixels[4] = [9, 8, 7];
        let p = d.join("t.png");
        std::fs::write(&p, encode_png(&fb, Some(&meta())).unwrap()).unwrap();
        assert_eq!(read_meta(&p).unwrap(), meta());
        assert_eq!(read_pixels(&p).unwrap(), fb);
        assert_eq!(Framebuffer::load(&p).unwrap(), fb);
        // without --tile, no tile index
        let whole = TileMeta {
            tile: None,
            ..meta()
        };
        std::fs::write(&p, encode_png(&fb, Some(&whole)).unwrap()).unwrap();
        assert_eq!(read_meta(&p).unwrap(), whole);
        let _ = std::fs::remove_dir_all(&d);
    }

    /// A PNG without tile information reads back as its pixels and is no tile.
    #[test]
    fn plain_pngs_are_no_tiles() {
        let mut fb = Framebuffer::new(5, 3);
        for (i, p) in fb.pixels.iter_mut().enumerate() {
            *p = [i as u8 * 17, 255 - i as u8, 3];
        }
        let d = dir("same");
        let p = d.join("a.png");
        std::fs::write(&p, encode_png(&fb, None).unwrap()).unwrap();
        assert_eq!(read_pixels(&p).unwrap(), fb);
        assert!(matches!(read_meta(&p), Err(TileError::NoMeta)));
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn bad_files_are_named_for_what_they_are() {
        let d = dir("bad");
        let bmp = d.join("a.bmp");
        std::fs::write(&bmp, super::super::bmp::encode(&Framebuffer::new(2, 2))).unwrap();
        assert!(matches!(read_meta(&bmp), Err(TileError::NotPng(_))));
        assert!(matches!(
            read_meta(&d.join("none.png")),
            Err(TileError::Io(_))
        ));
        // a rectangle that does not fit the image
        let p = d.join("b.png");
        std::fs::write(
            &p,
            encode_png(&Framebuffer::new(4, 2), Some(&meta())).unwrap(),
        )
        .unwrap();
        let e = read_meta(&p).unwrap_err();
        assert_eq!(
            e.to_string(),
            "the image is 4x2, but its rectangle 2,5,1,2;2,5,3,4 is 3x2"
        );
        assert_eq!(parse_rect("0,4,0,3"), Some([0, 4, 0, 3]));
        assert_eq!(
            parse_rects("0,4,0,3;2,6,5,6"),
            Some(vec![[0, 4, 0, 3], [2, 6, 5, 6]])
        );
        assert_eq!(parse_rects("0,4,0,3;2,5,5,6"), None);
        assert_eq!(parse_rects(""), None);
        for bad in ["", "1,2,3", "4,4,0,1", "0,1,2,1", "0,1,0,-1", "0,1,0,1,5"] {
            assert_eq!(parse_rect(bad), None, "{bad}");
        }
        let _ = std::fs::remove_dir_all(&d);
    }
}

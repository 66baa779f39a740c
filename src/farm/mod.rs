//! Work split for render farms: the pieces of a frame (`--tile I/N`, `--crop`), ranges of
//! frames of a camera path (`--frames A..B`) and their file names (`f_%04d.png`), and the
//! digest a piece records ([`digest`]). The commands are in `src/main.rs`, the
//! assembler in [`crate::output::assemble`], the scripts in `farm/`.
//!
//! A tile is a set of interleaved stripes of whole rows: the frame is cut into N × m
//! stripes (m up to [`STRIPES`] per tile, each at least two rows high and an even number
//! of rows, so that the frame loop's 4 × 2 sample blocks stay full), and tile I takes
//! stripes I, I + N, I + 2N, ... Every tile thus samples the whole height of the frame,
//! sky and floor alike, and takes about the same time, where contiguous bands of rows
//! differ tenfold (benches/README.md), and a frame split over N machines is as late as
//! its slowest tile. Stripes of whole rows keep any N up to the height possible (a grid
//! of rectangles needs N to factor).

pub mod digest;

use std::path::PathBuf;

use rayon::prelude::*;

use crate::output::Framebuffer;
use crate::parallel::{parallel, with_threads};
use crate::render::prepared::Prepared;
use crate::render::{PixelRect, RenderSettings, RenderStats, Rendered};

/// `I/N` of `--tile`: I from 0, I < N.
pub fn parse_tile(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected I/N with 0 <= I < N (tile I of N, from 0), got '{s}'");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let i: u32 = i.trim().parse().map_err(|_| bad())?;
    let n: u32 = n.trim().parse().map_err(|_| bad())?;
    if n == 0 {
        return Err(format!("N must be at least 1, got '{s}'"));
    }
    if i >= n {
        return Err(format!(
            "tile {i} of {n} does not exist (tiles are numbered 0 to {}), got '{s}'",
            n - 1
        ));
    }
    Ok((i, n))
}

/// Most stripes a tile takes: more balance the tiles' times better, each costs one call
/// of the frame loop.
pub const STRIPES: u32 = 16;

/// The stripes of tile `index` of `count` of a `width × height` frame, top to bottom
/// (adjacent stripes merged: one tile of one is the whole frame), each `min_rows` high
/// at least where the frame allows (a sampler that reads a margin around every stripe
/// wants them tall: [`crate::render::frame::Sampler::min_stripe_rows`]).
///
/// The frame is cut into m periods of N stripes; in each period every tile has one
/// stripe, in tile order in even periods and reversed in odd ones (so that a tile's
/// place within a period evens out over the periods); tiles get the same number of rows
/// to within two, split over their m stripes as evenly as whole row pairs allow.
pub fn tile_rects(
    index: u32,
    count: u32,
    (width, height): (u32, u32),
    min_rows: u32,
) -> Result<Vec<PixelRect>, String> {
    if count > height {
        return Err(format!(
            "{count} tiles of a frame {height} rows high: a tile takes whole rows, one at least"
        ));
    }
    let periods = (height / (min_rows.max(2) * count)).clamp(1, STRIPES) as u64;
    let (n, i) = (count as u64, index as u64);
    // rows counted in pairs where every stripe can have one pair at least (the last
    // stripe of the frame takes an odd row)
    let unit = if height as u64 >= 2 * n * periods {
        2
    } else {
        1
    };
    let units = height as u64 / unit;
    let split = |total: u64, parts: u64, k: u64| (k + 1) * total / parts - k * total / parts;
    let stripe = |tile: u64, period: u64| split(split(units, n, tile), periods, period);
    let mut rects: Vec<PixelRect> = Vec::new();
    let mut y = 0u64;
    for period in 0..periods {
        for place in 0..n {
            let tile = if period % 2 == 0 {
                place
            } else {
                n - 1 - place
            };
            let y1 = y + unit * stripe(tile, period);
            let y1 = if period + 1 == periods && place + 1 == n {
                height as u64
            } else {
                y1
            };
            if tile == i {
                match rects.last_mut() {
                    Some(last) if last.y1 as u64 == y => last.y1 = y1 as u32,
                    _ => rects.push(PixelRect {
                        x0: 0,
                        x1: width,
                        y0: y as u32,
                        y1: y1 as u32,
                    }),
                }
            }
            y = y1;
        }
    }
    Ok(rects)
}

/// A piece of a frame: its rectangles' pixels stacked top to bottom (all of one width).
pub struct Piece {
    pub image: Framebuffer,
    pub rects: Vec<PixelRect>,
    pub stats: RenderStats,
}

/// Renders the rectangles `rects` (of one width) of the frame `settings` describes,
/// each as a crop (the same pixels as the whole frame's), the rectangles side by side on
/// the thread pool. Under a profile's `resolution_scale` < 1 the renderer renders the
/// whole scaled frame for any crop: then the rectangles are cut from one crop around
/// them all.
pub fn render_piece(prepared: &Prepared, settings: &RenderSettings, rects: &[PixelRect]) -> Piece {
    let start = std::time::Instant::now();
    let crop = |rect: PixelRect, progress: bool| RenderSettings {
        crop: Some(rect),
        progress,
        ..settings.clone()
    };
    let mut stats = RenderStats::default();
    let images: Vec<Framebuffer> = if rects.len() > 1 && prepared.profile().resolution_scale < 1.0 {
        let around = PixelRect {
            x0: rects.iter().map(|r| r.x0).min().unwrap_or(0),
            x1: rects.iter().map(|r| r.x1).max().unwrap_or(0),
            y0: rects.iter().map(|r| r.y0).min().unwrap_or(0),
            y1: rects.iter().map(|r| r.y1).max().unwrap_or(0),
        };
        let all = prepared.render(&crop(around, settings.progress));
        stats = all.stats;
        rects.iter().map(|r| cut(&all.image, around, *r)).collect()
    } else {
        // (one progress bar: a single rectangle's)
        let progress = settings.progress && rects.len() == 1;
        let one = |r: &PixelRect| prepared.render(&crop(*r, progress));
        let parts: Vec<Rendered> = with_threads(settings.threads, || {
            if parallel() {
                rects.par_iter().map(one).collect()
            } else {
                rects.iter().map(one).collect()
            }
        });
        parts
            .into_iter()
            .map(|p| {
                stats.add(&p.stats);
                p.image
            })
            .collect()
    };
    let width = rects.first().map_or(0, |r| r.width());
    let height = rects.iter().map(|r| r.height()).sum();
    let mut image = Framebuffer::new(width, height);
    let mut at = 0;
    for part in &images {
        image.pixels[at..at + part.pixels.len()].copy_from_slice(&part.pixels);
        at += part.pixels.len();
    }
    stats.elapsed = start.elapsed();
    Piece {
        image,
        rects: rects.to_vec(),
        stats,
    }
}

/// The pixels `rect` of `image`, which holds the pixels `at` of the frame.
fn cut(image: &Framebuffer, at: PixelRect, rect: PixelRect) -> Framebuffer {
    let mut out = Framebuffer::new(rect.width(), rect.height());
    for (dy, row) in out.pixels.chunks_mut(rect.width() as usize).enumerate() {
        let y = (rect.y0 - at.y0) as usize + dy;
        let from = y * at.width() as usize + (rect.x0 - at.x0) as usize;
        row.copy_from_slice(&image.pixels[from..from + row.len()]);
    }
    out
}

/// `X0,X1,Y0,Y1` of `--crop` (half-open pixel ranges), not yet checked against a frame.
pub fn parse_crop(s: &str) -> Result<PixelRect, String> {
    let bad = || format!("expected X0,X1,Y0,Y1 (pixels, [X0,X1) x [Y0,Y1)), got '{s}'");
    let v: Vec<u32> = s
        .split(',')
        .map(|p| p.trim().parse::<u32>().ok())
        .collect::<Option<_>>()
        .ok_or_else(bad)?;
    let [x0, x1, y0, y1] = v[..] else {
        return Err(bad());
    };
    let rect = PixelRect { x0, x1, y0, y1 };
    if rect.is_empty() {
        return Err(format!(
            "empty rectangle: X0 < X1 and Y0 < Y1 needed, got '{s}'"
        ));
    }
    Ok(rect)
}

/// `crop` checked against a `width × height` frame.
pub fn check_crop(crop: PixelRect, width: u32, height: u32) -> Result<PixelRect, String> {
    if !crop.inside(&PixelRect::full(width, height)) {
        return Err(format!(
            "{},{},{},{} lies outside the {width}x{height} frame",
            crop.x0, crop.x1, crop.y0, crop.y1
        ));
    }
    Ok(crop)
}

/// `A..B` (frames A to B, inclusive, from 0) or `A` (one frame) of `--frames`.
pub fn parse_frames(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected A..B (frames A to B, from 0, inclusive) or A, got '{s}'");
    let number = |t: &str| t.trim().parse::<u32>().map_err(|_| bad());
    let (a, b) = match s.split_once("..") {
        Some((a, b)) => (number(a)?, number(b)?),
        None => {
            let a = number(s)?;
            (a, a)
        }
    };
    if a > b {
        return Err(format!("reversed range: {a} > {b} in '{s}'"));
    }
    Ok((a, b))
}

/// `(first, last)` checked against a path of `count` cameras.
pub fn check_frames(frames: (u32, u32), count: usize) -> Result<(u32, u32), String> {
    if count == 0 {
        return Err("the camera path has no cameras".into());
    }
    if frames.1 as usize >= count {
        return Err(format!(
            "{}..{}: the camera path has {count} cameras, frames 0..{}",
            frames.0,
            frames.1,
            count - 1
        ));
    }
    Ok(frames)
}

/// A printf-style file name pattern with one frame number, as ffmpeg's image sequences
/// read them: `%d` or `%0Nd` (zero-padded to N digits), `%%` for a `%`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FramePattern {
    prefix: String,
    /// Digits to pad to (0: none).
    width: usize,
    suffix: String,
}

impl FramePattern {
    pub fn parse(s: &str) -> Result<FramePattern, String> {
        let mut parts: Vec<String> = vec![String::new()];
        let mut width = 0;
        let mut chars = s.chars().peekable();
        while let Some(c) = chars.next() {
            if c != '%' {
                parts.last_mut().expect("one part at least").push(c);
                continue;
            }
            if chars.peek() == Some(&'%') {
                chars.next();
                parts.last_mut().expect("one part at least").push('%');
                continue;
            }
            let mut spec = String::new();
            while let Some(&d) = chars.peek().filter(|d| d.is_ascii_digit()) {
                spec.push(d);
                chars.next();
            }
            if chars.next() != Some('d') {
                return Err(format!(
                    "'{s}': only %d or %0Nd (the frame number, zero-padded to N digits) and %% may follow a %"
                ));
            }
            width = match spec.as_str() {
                "" | "0" => 0,
                _ if spec.starts_with('0') && spec.len() > 1 => spec[1..]
                    .parse()
                    .ok()
                    .filter(|&n: &usize| n <= 32)
                    .ok_or_else(|| format!("'{s}': %{spec}d pads to at most 32 digits"))?,
                _ => {
                    return Err(format!(
                        "'{s}': %{spec}d pads with spaces in printf and zeros in ffmpeg: write %0{spec}d"
                    ));
                }
            };
            parts.push(String::new());
        }
        match <[String; 2]>::try_from(parts) {
            Ok([prefix, suffix]) => Ok(FramePattern {
                prefix,
                width,
                suffix,
            }),
            Err(parts) if parts.len() == 1 => Err(format!(
                "'{s}' has no frame number: name the frames with %d or %04d (f_%04d.png)"
            )),
            Err(_) => Err(format!("'{s}' has more than one frame number (%d)")),
        }
    }

    /// The file name of frame `n`.
    pub fn name(&self, n: u32) -> PathBuf {
        PathBuf::from(format!(
            "{}{:0width$}{}",
            self.prefix,
            n,
            self.suffix,
            width = self.width
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_are_interleaved_stripes_that_cover_the_frame_evenly() {
        for (w, h, n) in [
            (1024, 576, 4),
            (512, 288, 3),
            (384, 384, 3),
            (3840, 2160, 16),
            (3840, 2160, 64),
            (5, 7, 7),
            (9, 7, 3),
            (9, 1000, 1),
        ] {
            let tiles: Vec<Vec<PixelRect>> = (0..n)
                .map(|i| tile_rects(i, n, (w, h), 2).unwrap())
                .collect();
            // every row in exactly one tile
            let mut owner = vec![None; h as usize];
            for (i, rects) in tiles.iter().enumerate() {
                for r in rects {
                    assert_eq!((r.x0, r.x1), (0, w));
                    assert!(!r.is_empty());
                    for y in r.y0..r.y1 {
                        assert_eq!(owner[y as usize], None, "row {y} twice");
                        owner[y as usize] = Some(i);
                    }
                }
                // top to bottom, adjacent stripes merged
                for pair in rects.windows(2) {
                    assert!(pair[0].y1 < pair[1].y0);
                }
            }
            assert!(
                owner.iter().all(Option::is_some),
                "{w}x{h}/{n}: a row in no tile"
            );
            // even stripes where the frame has two rows a stripe, tiles within
            // two rows (one pair) of each other, and one more for an odd height
            let m = (h / (2 * n)).clamp(1, STRIPES);
            let rows: Vec<u32> = tiles
                .iter()
                .map(|t| t.iter().map(|r| r.height()).sum())
                .collect();
            let (lo, hi) = (rows.iter().min().unwrap(), rows.iter().max().unwrap());
            assert!(hi - lo <= 2 + h % 2, "{w}x{h}/{n}: {rows:?}");
            if h >= 2 * n * m && n > 1 {
                for r in tiles.iter().flatten().filter(|r| r.y1 != h) {
                    assert!(r.y0 % 2 == 0 && r.y1 % 2 == 0, "{w}x{h}/{n}: {r:?}");
                }
            }
        }
        // 4K in 16: 16 stripes each, sampling the whole height
        let t = tile_rects(5, 16, (3840, 2160), 2).unwrap();
        assert_eq!(t.len(), 16);
        assert!(t[0].y0 < 200 && t[15].y1 > 1900);
        // a tile's place in the periods alternates: 5 above 10, then below
        let u = tile_rects(10, 16, (3840, 2160), 2).unwrap();
        assert!(t[0].y0 < u[0].y0 && t[1].y0 > u[1].y0);
        assert!(t[0].y0 > 0 && u[1].y1 < 2 * 2160 / 16);
        assert_eq!(
            tile_rects(0, 1, (9, 1000), 2).unwrap(),
            [PixelRect::full(9, 1000)]
        );
        assert!(tile_rects(0, 8, (10, 7), 2).is_err());
        // taller stripes when asked: 1080 rows in 4 tiles, 5 periods of 48-row stripes
        // or more (the end tiles' stripes meet at the turns and merge)
        for i in 0..4 {
            let t = tile_rects(i, 4, (1920, 1080), 48).unwrap();
            assert_eq!(t.len(), if i == 1 || i == 2 { 5 } else { 3 }, "{t:?}");
            assert!(t.iter().all(|r| r.height() >= 48), "{t:?}");
        }
        // and never fewer than one stripe a tile
        assert_eq!(tile_rects(3, 16, (1920, 1080), 48).unwrap().len(), 1);
    }

    #[test]
    fn tile_and_crop_arguments_are_checked() {
        assert_eq!(parse_tile("3/8"), Ok((3, 8)));
        assert_eq!(parse_tile("0/1"), Ok((0, 1)));
        for bad in ["4/4", "0/0", "5", "-1/4", "a/b", "1/", "/4", "1/4/5"] {
            assert!(parse_tile(bad).is_err(), "{bad}");
        }
        assert!(parse_tile("4/4").unwrap_err().contains("numbered 0 to 3"));
        let r = parse_crop("3,10,0,2").unwrap();
        assert_eq!((r.x0, r.x1, r.y0, r.y1), (3, 10, 0, 2));
        for bad in [
            "",
            "1,2,3",
            "3,3,0,1",
            "0,1,5,2",
            "0,1,0,-1",
            "0,1,0,1,0",
            "a,1,0,1",
        ] {
            assert!(parse_crop(bad).is_err(), "{bad}");
        }
        assert!(check_crop(r, 10, 2).is_ok());
        assert_eq!(
            check_crop(r, 9, 2).unwrap_err(),
            "3,10,0,2 lies outside the 9x2 frame"
        );
    }

    #[test]
    fn frame_ranges_are_inclusive_and_checked_against_the_path() {
        assert_eq!(parse_frames("2..5"), Ok((2, 5)));
        assert_eq!(parse_frames("7"), Ok((7, 7)));
        assert!(parse_frames("5..2").unwrap_err().contains("reversed"));
        for bad in ["", "..", "1..", "a..2", "-1..2", "1...2"] {
            assert!(parse_frames(bad).is_err(), "{bad}");
        }
        assert_eq!(check_frames((0, 3), 4), Ok((0, 3)));
        assert!(
            check_frames((0, 4), 4)
                .unwrap_err()
                .contains("4 cameras, frames 0..3")
        );
        assert!(check_frames((0, 0), 0).is_err());
    }

    #[test]
    fn patterns_name_frames_as_ffmpeg_reads_them() {
        let p = FramePattern::parse("frames/f_%04d.png").unwrap();
        assert_eq!(p.name(7), PathBuf::from("frames/f_0007.png"));
        assert_eq!(p.name(123456), PathBuf::from("frames/f_123456.png"));
        let p = FramePattern::parse("100%%_%d.bmp").unwrap();
        assert_eq!(p.name(12), PathBuf::from("100%_12.bmp"));
        for (bad, says) in [
            ("frames/f.png", "no frame number"),
            ("f_%%d.png", "no frame number"),
            ("f_%d_%d.png", "more than one"),
            ("f_%4d.png", "write %04d"),
            ("f_%s.png", "only %d or %0Nd"),
            ("f_%", "only %d or %0Nd"),
            ("f_%099d.png", "at most 32"),
        ] {
            let e = FramePattern::parse(bad).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
    }
}

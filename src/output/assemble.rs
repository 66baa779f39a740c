//! Puts the pieces of a frame back together (`octaray assemble`): each PNG piece records
//! its rectangle, the frame size and the digest of its settings ([`super::tile`]).
//! Refused, naming the piece: a file that is no piece, pieces of different frame sizes or
//! settings (digests), a rectangle outside the frame, overlaps; and pieces that leave
//! pixels uncovered (naming the missing `--tile I/N` when the pieces are tiles).

use std::path::{Path, PathBuf};

use super::Framebuffer;
use super::tile::{TileError, TileMeta, read_meta, read_pixels, rect_text};

/// A frame put together, and what it records.
pub struct Assembled {
    pub image: Framebuffer,
    /// The pieces' settings, for the whole frame.
    pub meta: TileMeta,
}

#[derive(Debug, thiserror::Error)]
pub enum AssembleError {
    #[error("no tiles given")]
    Empty,
    /// A piece that cannot be read or is no piece.
    #[error("{path}: {source}")]
    Tile { path: String, source: TileError },
    /// A piece that does not fit with the others.
    #[error("{path}: {message}")]
    Refused { path: String, message: String },
    /// Pixels no piece covers.
    #[error("{0}")]
    Gap(String),
}

fn name(p: &Path) -> String {
    p.display().to_string()
}

/// Reads the pieces' records, checks that they tile one frame exactly, then reads their
/// pixels into it.
pub fn assemble(paths: &[PathBuf]) -> Result<Assembled, AssembleError> {
    let metas = paths
        .iter()
        .map(|p| {
            read_meta(p).map_err(|source| AssembleError::Tile {
                path: name(p),
                source,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let first = metas.first().ok_or(AssembleError::Empty)?;
    check_fit(paths, &metas)?;
    check_covered(first, &metas)?;
    let (w, h) = first.frame;
    let mut image = Framebuffer::new(w, h);
    for (path, meta) in paths.iter().zip(&metas) {
        let piece = read_pixels(path).map_err(|source| AssembleError::Tile {
            path: name(path),
            source,
        })?;
        if (piece.width, piece.height) != (meta.width(), meta.height()) {
            // (the header was checked: the file changed in between)
            return Err(AssembleError::Refused {
                path: name(path),
                message: "changed while being read".into(),
            });
        }
        // the rectangles' rows, stacked top to bottom
        let mut rows = piece.pixels.chunks(piece.width as usize);
        for &[x0, _, y0, y1] in &meta.rects {
            for (y, row) in (y0..y1).zip(rows.by_ref()) {
                let at = y as usize * w as usize + x0 as usize;
                image.pixels[at..at + row.len()].copy_from_slice(row);
            }
        }
    }
    Ok(Assembled {
        image,
        meta: first.whole(),
    })
}

/// Same frame size and digest as the first piece, inside the frame, no overlaps.
fn check_fit(paths: &[PathBuf], metas: &[TileMeta]) -> Result<(), AssembleError> {
    let (first_path, first) = (&paths[0], &metas[0]);
    let (w, h) = first.frame;
    for (k, (path, meta)) in paths.iter().zip(metas).enumerate() {
        let refuse = |message: String| AssembleError::Refused {
            path: name(path),
            message,
        };
        if meta.frame != first.frame {
            return Err(refuse(format!(
                "a piece of a {}x{} frame, but {} is of a {w}x{h} frame",
                meta.frame.0,
                meta.frame.1,
                name(first_path)
            )));
        }
        if meta.digest != first.digest {
            return Err(refuse(format!(
                "rendered from another scene or other settings than {} (digest {} against {}){}",
                name(first_path),
                meta.digest,
                first.digest,
                differences(&meta.settings, &first.settings)
            )));
        }
        for (j, &rect) in meta.rects.iter().enumerate() {
            let [x0, x1, y0, y1] = rect;
            if x1 > w || y1 > h || x0 >= x1 || y0 >= y1 {
                return Err(refuse(format!(
                    "rectangle {} lies outside the {w}x{h} frame",
                    rect_text(rect)
                )));
            }
            // against the pieces before it, and its own rectangles before this one
            let earlier = paths
                .iter()
                .zip(metas)
                .take(k)
                .flat_map(|(p, m)| m.rects.iter().map(move |r| (p, *r, false)))
                .chain(meta.rects[..j].iter().map(|r| (path, *r, true)));
            for (other_path, [a0, a1, b0, b1], own) in earlier {
                let (ix0, ix1, iy0, iy1) = (x0.max(a0), x1.min(a1), y0.max(b0), y1.min(b1));
                if ix0 < ix1 && iy0 < iy1 {
                    let what = if !own && super::same_file(path, other_path) {
                        format!("given twice (also as {})", name(other_path))
                    } else {
                        format!(
                            "overlaps {} in pixels {} (X0,X1,Y0,Y1)",
                            name(other_path),
                            rect_text([ix0, ix1, iy0, iy1])
                        )
                    };
                    return Err(refuse(what));
                }
            }
        }
    }
    Ok(())
}

/// The lines of `settings` that `reference` does not have, for a message.
fn differences(settings: &str, reference: &str) -> String {
    let theirs: Vec<&str> = reference.lines().collect();
    let lines: Vec<String> = settings
        .lines()
        .filter(|l| !theirs.contains(l))
        .map(|l| format!("\n  this piece: {l}"))
        .collect();
    let missing: Vec<String> = theirs
        .iter()
        .filter(|l| !settings.lines().any(|m| m == **l))
        .map(|l| format!("\n  the first:  {l}"))
        .collect();
    lines.concat() + &missing.concat()
}

/// Every pixel covered (the pieces do not overlap: their areas add up to the frame's
/// exactly when they cover it).
fn check_covered(first: &TileMeta, metas: &[TileMeta]) -> Result<(), AssembleError> {
    let (w, h) = first.frame;
    let area: u64 = metas
        .iter()
        .map(|m| m.width() as u64 * m.height() as u64)
        .sum();
    let rects: Vec<[u32; 4]> = metas.iter().flat_map(|m| m.rects.iter().copied()).collect();
    let total = w as u64 * h as u64;
    if area == total {
        return Ok(());
    }
    // the first uncovered pixel, row by row
    let (x, y) = (0..h)
        .find_map(|y| {
            let mut spans: Vec<(u32, u32)> = rects
                .iter()
                .filter(|r| r[2] <= y && y < r[3])
                .map(|r| (r[0], r[1]))
                .collect();
            spans.sort_unstable();
            let mut x = 0;
            for (x0, x1) in spans {
                if x0 > x {
                    break;
                }
                x = x.max(x1);
            }
            (x < w).then_some((x, y))
        })
        .unwrap_or((0, 0));
    let mut message = format!(
        "the pieces leave {} of the {w}x{h} frame's pixels uncovered, the first at ({x}, {y})",
        total - area
    );
    if let Some(missing) = missing_tiles(metas) {
        message += &format!("; missing: {missing}");
    }
    Err(AssembleError::Gap(message))
}

/// `tile 2/8, tile 5/8` when every piece is a `--tile I/N` of one N.
fn missing_tiles(metas: &[TileMeta]) -> Option<String> {
    let n = metas.first()?.tile?.1;
    let mut present = vec![false; n as usize];
    for m in metas {
        let (i, count) = m.tile?;
        if count != n {
            return None;
        }
        present[i as usize] = true;
    }
    let missing: Vec<String> = (0..n)
        .filter(|&i| !present[i as usize])
        .map(|i| format!("tile {i}/{n}"))
        .collect();
    (!missing.is_empty()).then(|| missing.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::tile::encode_png;

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("octaray-assemble-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// A 6 × 4 frame whose pixel (x, y) is (x, y, 7).
    fn frame() -> Framebuffer {
        let mut fb = Framebuffer::new(6, 4);
        for y in 0..4 {
            for x in 0..6 {
                fb.pixels[y * 6 + x] = [x as u8, y as u8, 7];
            }
        }
        fb
    }

    fn meta(rect: [u32; 4], tile: Option<(u32, u32)>) -> TileMeta {
        TileMeta {
            frame: (6, 4),
            rects: vec![rect],
            tile,
            digest: "d1".into(),
            settings: "scene: a\ncamera: b".into(),
        }
    }

    /// Writes the piece `meta.rects` of [`frame`] as `dir/name`.
    fn piece(dir: &Path, name: &str, meta: &TileMeta) -> PathBuf {
        let whole = frame();
        let mut fb = Framebuffer::new(meta.width(), meta.height());
        let mut at = 0;
        for &[x0, x1, y0, y1] in &meta.rects {
            for y in y0..y1 {
                for x in x0..x1 {
                    if x < whole.width && y < whole.height {
                        fb.pixels[at] = whole.get(x, y);
                    }
                    at += 1;
                }
            }
        }
        let p = dir.join(name);
        std::fs::write(&p, encode_png(&fb, Some(meta)).unwrap()).unwrap();
        p
    }

    #[test]
    fn pieces_in_any_order_make_the_frame() {
        let d = dir("ok");
        let a = piece(&d, "a.png", &meta([0, 6, 0, 1], Some((0, 3))));
        let b = piece(&d, "b.png", &meta([0, 2, 1, 4], None));
        let c = piece(&d, "c.png", &meta([2, 6, 1, 4], None));
        let out = assemble(&[c, a.clone(), b]).unwrap();
        assert_eq!(out.image, frame());
        // stripes: rows 1 and 3, rows 2
        let s = TileMeta {
            rects: vec![[0, 6, 1, 2], [0, 6, 3, 4]],
            ..meta([0, 0, 0, 0], Some((0, 2)))
        };
        let s = piece(&d, "s.png", &s);
        let t = piece(&d, "t.png", &meta([0, 6, 2, 3], Some((1, 2))));
        let out = assemble(&[t, a, s]).unwrap();
        assert_eq!(out.image, frame());
        assert_eq!(out.meta, meta([0, 6, 0, 4], None));
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn gaps_overlaps_sizes_and_foreign_pieces_are_refused_by_name() {
        let d = dir("bad");
        let t = |i| Some((i, 3));
        let a = piece(&d, "a.png", &meta([0, 6, 0, 1], t(0)));
        let b = piece(&d, "b.png", &meta([0, 6, 1, 3], t(1)));
        let c = piece(&d, "c.png", &meta([0, 6, 3, 4], t(2)));
        let err = |paths: &[&PathBuf]| {
            let owned: Vec<PathBuf> = paths.iter().map(|p| (*p).clone()).collect();
            match assemble(&owned) {
                Err(e) => e.to_string(),
                Ok(_) => panic!("assembled {paths:?}"),
            }
        };
        let gap = err(&[&a, &c]);
        assert!(gap.contains("leave 12 of the 6x4"), "{gap}");
        assert!(
            gap.contains("first at (0, 1)") && gap.ends_with("missing: tile 1/3"),
            "{gap}"
        );
        let twice = err(&[&a, &b, &c, &b]);
        assert!(twice.starts_with(&b.display().to_string()) && twice.contains("given twice"));
        let over = piece(&d, "over.png", &meta([4, 6, 2, 4], None));
        let e = err(&[&a, &b, &c, &over]);
        assert!(e.starts_with(&over.display().to_string()), "{e}");
        assert!(e.contains("overlaps") && e.contains("4,6,2,3"), "{e}");
        let foreign = piece(
            &d,
            "foreign.png",
            &TileMeta {
                digest: "d2".into(),
                settings: "scene: a\ncamera: c".into(),
                ..meta([0, 6, 3, 4], t(2))
            },
        );
        let e = err(&[&a, &b, &foreign]);
        assert!(e.starts_with(&foreign.display().to_string()), "{e}");
        assert!(e.contains("another scene or other settings"), "{e}");
        assert!(
            e.contains("this piece: camera: c") && e.contains("the first:  camera: b"),
            "{e}"
        );
        let big = piece(
            &d,
            "big.png",
            &TileMeta {
                frame: (6, 5),
                ..meta([0, 6, 3, 4], t(2))
            },
        );
        let e = err(&[&a, &b, &big]);
        assert!(e.contains("a piece of a 6x5 frame"), "{e}");
        let outside = piece(
            &d,
            "outside.png",
            &TileMeta {
                frame: (6, 4),
                ..meta([5, 7, 3, 4], None)
            },
        );
        let e = err(&[&a, &b, &outside]);
        assert!(e.contains("lies outside the 6x4 frame"), "{e}");
        let e = err(&[&a, &d.join("missing.png")]);
        assert!(e.contains("missing.png: cannot read"), "{e}");
        assert!(matches!(assemble(&[]), Err(AssembleError::Empty)));
        let _ = std::fs::remove_dir_all(&d);
    }
}

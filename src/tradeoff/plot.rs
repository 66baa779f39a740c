//! The trade-off plot: per scene, the error against the true picture versus time, a line
//! through its ladder of profiles (the frontier), drawn with `plotters` as SVG.

use plotters::prelude::*;

use super::{Row, ladder};
use crate::render::profile::RenderPath;

const SIZE: (u32, u32) = (1100, 700);

/// Exact images (infinite PSNR) are drawn at this height.
const EXACT_DB: f64 = 80.0;

/// The plot of `rows` as an SVG document: one line per (scene, size) through its
/// packet-path profiles, the reference path's points as crosses of the same colour.
pub fn svg(rows: &[Row]) -> String {
    let mut out = String::new();
    draw(rows, &mut out).expect("drawing into a String cannot fail");
    out
}

fn db(r: &Row) -> f64 {
    r.truth.psnr_db.min(EXACT_DB)
}

fn draw(rows: &[Row], out: &mut String) -> Result<(), DrawingAreaErrorKind<std::io::Error>> {
    let root = SVGBackend::with_string(out, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let ms = |r: &Row| (r.seconds * 1e3).max(1e-3);
    let (lo, hi) = rows.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
        (lo.min(ms(r)), hi.max(ms(r)))
    });
    let (lo, hi) = if rows.is_empty() {
        (1.0, 10.0)
    } else {
        (lo / 1.5, hi * 1.5)
    };
    let (db_lo, db_hi) = rows.iter().fold((f64::INFINITY, 0.0f64), |(a, b), r| {
        (a.min(db(r)), b.max(db(r)))
    });
    let (db_lo, db_hi) = if rows.is_empty() {
        (10.0, 60.0)
    } else {
        (
            (db_lo / 5.0).floor() * 5.0,
            (db_hi / 5.0).ceil() * 5.0 + 2.0,
        )
    };
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "octaray tradeoff: error against the true picture versus time",
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d((lo..hi).log_scale(), db_lo..db_hi)?;
    chart
        .configure_mesh()
        .x_desc("time per image, ms (log scale, preparation included)")
        .y_desc("PSNR against the true picture, dB (higher is closer)")
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16))
        .draw()?;
    // one line per (scene, size), in order of first appearance
    let mut lines: Vec<(&str, u32)> = Vec::new();
    for r in rows {
        if !lines.contains(&(r.scene.as_str(), r.size)) {
            lines.push((&r.scene, r.size));
        }
    }
    for (i, &(scene, size)) in lines.iter().enumerate() {
        let colour = Palette99::pick(i).to_rgba();
        let points: Vec<(f64, f64)> = ladder(rows, scene, size)
            .iter()
            .map(|r| (ms(r), db(r)))
            .collect();
        chart
            .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))?
            .label(format!("{scene} {size}²"))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled())))?;
        let reference = rows
            .iter()
            .filter(|r| r.scene == scene && r.size == size && r.path == RenderPath::Reference);
        chart.draw_series(
            reference.map(|r| Cross::new((ms(r), db(r)), 5, colour.stroke_width(2))),
        )?;
        // the first line's points are named after their profiles
        if i == 0 {
            for r in ladder(rows, scene, size) {
                chart.draw_series(std::iter::once(Text::new(
                    r.profile.clone(),
                    (ms(r), db(r) + 0.8),
                    ("sans-serif", 14).into_font().color(&BLACK),
                )))?;
            }
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .label_font(("sans-serif", 13))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    root.draw(&Text::new(
        "dots: packet profiles (a line per scene through its ladder); crosses: reference (f64, one sample per pixel)",
        (70, SIZE.1 as i32 - 16),
        ("sans-serif", 13).into_font().color(&BLACK),
    ))?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::RenderStats;
    use crate::render::diff::ImageDiff;
    use crate::tradeoff::truth::TruthError;

    fn row(scene: &str, profile: &str, path: RenderPath, ms: f64, db: f64) -> Row {
        Row {
            scene: scene.into(),
            size: 64,
            profile: profile.into(),
            path,
            seconds: ms / 1e3,
            stats: RenderStats::default(),
            speedup: 1.0,
            diff: ImageDiff::default(),
            truth: TruthError {
                psnr_db: db,
                ..TruthError::default()
            },
        }
    }

    #[test]
    fn one_line_per_scene_with_its_legend_and_labelled_axes() {
        let p = RenderPath::Packet;
        let rows = [
            row("given", "reference", RenderPath::Reference, 40.0, 30.0),
            row("given", "fast", p, 4.0, 30.5),
            row("given", "quality", p, 12.0, 45.0),
            row("mirrors", "fast", p, 5.0, 28.0),
            row("mirrors", "quality", p, 15.0, f64::INFINITY),
        ];
        let svg = svg(&rows);
        assert!(svg.starts_with("<svg"), "{}", &svg[..80]);
        assert!(svg.contains("given 64²") && svg.contains("mirrors 64²"));
        assert!(
            svg.contains("time per image, ms") && svg.contains("PSNR against the true picture")
        );
        // a polyline per scene: its ladder's points (the reference is a cross)
        assert!(svg.matches("<polyline").count() >= 2, "{svg}");
        assert!(
            svg.contains(">\nquality\n</text>"),
            "profiles of the first line are named"
        );
    }
}

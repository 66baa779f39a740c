//! The one frame loop: a rectangle of a frame rendered alone equals the same pixels of
//! the whole frame, byte for byte, on every profile and sampling (full frames,
//! supersampled, adaptive, reduced resolution, glass with its wavelengths and photon map).

use std::path::Path;

use octaray::render::profile::Profile;
use octaray::render::{PixelRect, RenderSettings};
use octaray::scene::Scene;
use octaray::scene::parse::parse_scene_file;

fn scene(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    parse_scene_file(&path)
        .unwrap_or_else(|e| panic!("{e}"))
        .scene
}

fn profiles() -> Vec<Profile> {
    let mut out: Vec<Profile> = Profile::NAMES
        .iter()
        .map(|n| Profile::by_name(n).unwrap())
        .collect();
    for text in [
        "samples_per_pixel = 4",
        "samples_per_pixel = 9",
        "path = \"reference\"\nsamples_per_pixel = 9",
        "triangle_test = \"moller\"\nshadow_any_hit = false",
        "sampler = \"adaptive\"\nsamples_per_pixel = 4\nthreshold = 0",
    ] {
        out.push(Profile::from_toml("custom", text, "custom.toml").unwrap());
    }
    out
}

/// Crops at odd offsets, single rows and columns, corners and the whole frame.
fn crops(w: u32, h: u32) -> Vec<PixelRect> {
    let r = |x0, x1, y0, y1| PixelRect { x0, x1, y0, y1 };
    vec![
        r(3, 37, 5, 29),
        r(0, w, 0, 1),
        r(w - 1, w, h - 1, h),
        r(17, 18, 0, h),
        r(1, w - 2, 7, 8),
        r(0, w, 0, h),
    ]
}

#[test]
fn a_rectangle_alone_equals_the_same_pixels_of_the_whole_frame() {
    let (w, h) = (45, 31);
    for name in ["given.txt", "prism.txt", "mirrors.txt", "quadric_cone.txt"] {
        let s = scene(name);
        for profile in profiles() {
            let prepared = profile.prepare(&s, octaray::scene::Camera::default().eye);
            let mut settings = RenderSettings::square(w);
            settings.height = h;
            let whole = prepared.render(&settings);
            assert_eq!(whole.rect, PixelRect::full(w, h));
            for crop in crops(w, h) {
                settings.crop = Some(crop);
                let part = prepared.render(&settings);
                assert_eq!(part.rect, crop);
                assert_eq!(part.image.width, crop.width());
                assert_eq!(part.image.height, crop.height());
                for y in crop.y0..crop.y1 {
                    for x in crop.x0..crop.x1 {
                        assert_eq!(
                            part.image.get(x - crop.x0, y - crop.y0),
                            whole.image.get(x, y),
                            "{name}, profile {:?}: pixel ({x}, {y}) of crop {crop:?}",
                            profile
                        );
                    }
                }
            }
        }
    }
}

//! Shared helpers of the integration tests: seeded ray sets, generated scenes, image
//! comparison with masks of legitimate differences, scratch directories and child
//! processes that clean up after themselves.
#![allow(dead_code)]

use std::ffi::OsStr;
use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::thread::sleep;
use std::time::{Duration, Instant};

use glam::DVec3;
use octaray::scene::{Camera, Material, Object, PointLight, Scene, Shape, SpotLight};

/// A small deterministic generator (SplitMix64), so no test depends on a crate's RNG.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f64()
    }
    pub fn vec_in(&mut self, lo: DVec3, hi: DVec3) -> DVec3 {
        DVec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }
    /// Uniform on the unit sphere.
    pub fn unit(&mut self) -> DVec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f64::consts::TAU);
        let s = (1.0 - z * z).sqrt();
        DVec3::new(s * phi.cos(), s * phi.sin(), z)
    }
}

pub fn material(rng: &mut Rng) -> Material {
    Material {
        color: DVec3::new(rng.f64(), rng.f64(), rng.f64()),
        ka: 0.3,
        kd: 0.3,
        ks: 0.3,
        kr: rng.range(0.0, 0.4),
        shine: rng.range(1.0, 20.0),
    }
}

/// A scene of `n` mixed primitives (spheres, triangles, clipped and unclipped
/// quadrics; no glass) scattered over the floor, lit by point lights and a spotlight.
pub fn generated_scene(n: usize, seed: u64) -> Scene {
    let mut rng = Rng(seed);
    let mut objects = Vec::with_capacity(n);
    let lo = DVec3::new(-80.0, -80.0, 0.0);
    let hi = DVec3::new(60.0, 60.0, 40.0);
    for k in 0..n {
        let c = rng.vec_in(lo, hi);
        let shape = match k % 10 {
            0..=3 => Shape::Sphere {
                center: c,
                radius: rng.range(0.5, 3.0),
            },
            4..=7 | 9 => {
                let s = rng.range(1.0, 5.0);
                Shape::Triangle {
                    v: [c, c + rng.unit() * s, c + rng.unit() * s],
                }
            }
            _ => {
                // an ellipsoid clipped to a box around it (some clip only one axis)
                let r = rng.range(1.0, 3.0);
                let coef = [
                    1.0,
                    1.0,
                    1.0,
                    0.0,
                    0.0,
                    0.0,
                    -2.0 * c.x,
                    -2.0 * c.y,
                    -2.0 * c.z,
                    c.length_squared() - r * r,
                ];
                let m = coef.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let full = rng.f64() < 0.8;
                let size = if full {
                    DVec3::new(2.0 * r, 2.0 * r, r * 1.5)
                } else {
                    DVec3::new(0.0, 0.0, r * 1.5)
                };
                Shape::Quadric(octaray::scene::Quadric {
                    coef: coef.map(|v| v / m),
                    min: c - DVec3::splat(r),
                    size,
                })
            }
        };
        objects.push(Object {
            shape,
            material: material(&mut rng),
        });
    }
    Scene {
        recursion_level: 3,
        pixels: 64,
        objects,
        point_lights: vec![
            PointLight {
                position: DVec3::new(70.0, 70.0, 70.0),
                color: DVec3::new(1.0, 0.8, 0.6),
            },
            PointLight {
                position: DVec3::new(-70.0, 60.0, 50.0),
                color: DVec3::new(0.3, 0.4, 1.0),
            },
        ],
        spot_lights: vec![SpotLight {
            position: DVec3::new(0.0, 0.0, 150.0),
            color: DVec3::new(0.0, 1.0, 0.0),
            direction: DVec3::NEG_Z,
            cutoff_deg: 25.0,
        }],
    }
}

/// Image comparison with masks of legitimate differences: the library's
/// (`octaray::render::diff`, also used by `octaray tradeoff`).
#[allow(unused_imports)]
pub use octaray::render::diff::{ImageDiff, compare};

/// Pixels of two images of one size whose channels differ by more than `tol`/255.
pub fn pixels_off(a: &[[u8; 3]], b: &[[u8; 3]], tol: u8) -> usize {
    assert_eq!(a.len(), b.len(), "images of different sizes");
    a.iter()
        .zip(b)
        .filter(|(a, b)| (0..3).any(|c| a[c].abs_diff(b[c]) > tol))
        .count()
}

/// The primary-hit object of each pixel on the reference path (−1 background, −2 floor).
pub fn reference_ids(scene: &Scene, camera: &Camera, size: u32) -> Vec<i64> {
    octaray::render::diff::reference_ids(scene, camera, size, size)
}

/// A directory of this test process, `octaray-<tag>-<pid>` under the system's temporary
/// directory: emptied when made (an earlier run of this pid may have left it) and removed
/// when dropped, also when the test fails, so that runs do not fill the disk.
pub struct Scratch(PathBuf);

impl Scratch {
    pub fn new(tag: &str) -> Scratch {
        let dir = std::env::temp_dir().join(format!("octaray-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }
}

impl Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<OsStr> for Scratch {
    fn as_ref(&self) -> &OsStr {
        self.0.as_os_str()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Stops and reaps a child process of this test when dropped: SIGTERM first (so Xvfb
/// removes its lock and socket files), SIGKILL if it is still there after 5 s.
pub struct ChildGuard(pub Child);

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if let Ok(None) = self.0.try_wait() {
            let _ = Command::new("kill").arg(self.0.id().to_string()).status();
            let start = Instant::now();
            while let Ok(None) = self.0.try_wait() {
                if start.elapsed() > Duration::from_secs(5) {
                    let _ = self.0.kill();
                    break;
                }
                sleep(Duration::from_millis(20));
            }
        }
        let _ = self.0.wait();
    }
}

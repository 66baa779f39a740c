//! The scene: plain f64 data, exactly what the scene file says, plus the fixed floor
//! and the default camera of `docs/scene-format.md`.
//!
//! Parsing ([`parse`]) produces a [`Scene`]; renderers read it and build their own
//! acceleration structures from it. Nothing here knows about rendering.

pub mod camera;
pub mod camera_path;
pub mod input;
pub mod mesh_cache;
pub mod obj;
pub mod parse;
pub mod text;

use glam::DVec3;

pub use camera::Camera;
pub use input::{MAX_INPUT, read_input};
pub use parse::{ParseError, parse_scene, parse_scene_file};

/// Surface parameters shared by every object kind (the assignment's `color`,
/// `coEfficients` and `shine`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub color: DVec3,
    /// Ambient coefficient.
    pub ka: f64,
    /// Diffuse coefficient.
    pub kd: f64,
    /// Specular coefficient.
    pub ks: f64,
    /// Mirror-reflection coefficient.
    pub kr: f64,
    /// Phong exponent.
    pub shine: f64,
}

/// Optical parameters of a dispersive (glass) object: `kt cauchy_a cauchy_b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Glass {
    /// Weight of transmitted light.
    pub kt: f64,
    /// Cauchy's A: n(λ) = a + b / λ², λ in micrometres.
    pub cauchy_a: f64,
    /// Cauchy's B in µm².
    pub cauchy_b: f64,
}

impl Glass {
    /// Refractive index at wavelength `lambda_um` (micrometres).
    pub fn index(&self, lambda_um: f64) -> f64 {
        self.cauchy_a + self.cauchy_b / (lambda_um * lambda_um)
    }
}

/// A general quadric F(x,y,z) = Ax² + By² + Cz² + Dxy + Exz + Fyz + Gx + Hy + Iz + J = 0,
/// clipped to an axis-aligned box. A box dimension of 0 means "no clipping on that axis".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quadric {
    /// A..J, divided at load by the largest magnitude (a geometric no-op that keeps
    /// every later product inside f32 range).
    pub coef: [f64; 10],
    /// Box corner (rx, ry, rz).
    pub min: DVec3,
    /// Box size (length, width, height); 0 = unclipped on that axis.
    pub size: DVec3,
}

impl Quadric {
    /// F at p.
    pub fn value(&self, p: DVec3) -> f64 {
        let [a, b, c, d, e, f, g, h, i, j] = self.coef;
        a * p.x * p.x
            + b * p.y * p.y
            + c * p.z * p.z
            + d * p.x * p.y
            + e * p.x * p.z
            + f * p.y * p.z
            + g * p.x
            + h * p.y
            + i * p.z
            + j
    }

    /// ∇F at p (the unnormalised surface normal).
    pub fn gradient(&self, p: DVec3) -> DVec3 {
        let [a, b, c, d, e, f, g, h, i, _] = self.coef;
        DVec3::new(
            2.0 * a * p.x + d * p.y + e * p.z + g,
            2.0 * b * p.y + d * p.x + f * p.z + h,
            2.0 * c * p.z + e * p.x + f * p.y + i,
        )
    }

    /// Whether p lies in the clipping box (inclusive; unclipped axes always pass).
    pub fn in_box(&self, p: DVec3) -> bool {
        let inside = |v: f64, lo: f64, size: f64| size == 0.0 || (v >= lo && v <= lo + size);
        inside(p.x, self.min.x, self.size.x)
            && inside(p.y, self.min.y, self.size.y)
            && inside(p.z, self.min.z, self.size.z)
    }

    /// True for the all-zero quadric, which is never hit.
    pub fn is_degenerate(&self) -> bool {
        self.coef.iter().all(|&c| c == 0.0)
    }
}

/// The geometric kinds a scene file can name.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    Sphere {
        center: DVec3,
        radius: f64,
    },
    /// Vertices in file order; the normal is (b − a) × (c − a).
    Triangle {
        v: [DVec3; 3],
    },
    Quadric(Quadric),
    /// Two parallel triangular ends a,b,c and d,e,f (a–d, b–e, c–f are the long edges).
    Prism {
        v: [DVec3; 6],
        glass: Glass,
    },
    /// A triangle mesh from an OBJ file (`mesh PATH.obj`), shared so that a million
    /// triangles stay one object (see [`obj`]).
    Mesh(std::sync::Arc<obj::Mesh>),
}

/// One object of the scene file: a shape and its material.
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    pub shape: Shape,
    pub material: Material,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    pub position: DVec3,
    pub color: DVec3,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpotLight {
    pub position: DVec3,
    pub color: DVec3,
    /// Unit axis of the cone.
    pub direction: DVec3,
    /// Half-angle of the cone in degrees, 0..=180. Hard edge.
    pub cutoff_deg: f64,
}

/// Everything a scene file describes. The floor is implicit (see [`Floor`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Camera rays are traced at level 1; a hit at level < recursion_level spawns a mirror ray.
    pub recursion_level: u32,
    /// The image is pixels × pixels.
    pub pixels: u32,
    pub objects: Vec<Object>,
    pub point_lights: Vec<PointLight>,
    pub spot_lights: Vec<SpotLight>,
}

/// The fixed checkerboard floor of every scene: z = 0, -500 <= x, y <= 500, 20-unit tiles.
pub struct Floor;

impl Floor {
    pub const HALF_WIDTH: f64 = 500.0;
    pub const TILE: f64 = 20.0;
    pub const MATERIAL: Material = Material {
        color: DVec3::ONE,
        ka: 0.4,
        kd: 0.2,
        ks: 0.2,
        kr: 0.2,
        shine: 1.0,
    };

    /// Tile colour at (x, y): white where floor((x+500)/20) + floor((y+500)/20) is even.
    pub fn color_at(x: f64, y: f64) -> DVec3 {
        let i = ((x + Self::HALF_WIDTH) / Self::TILE).floor() as i64;
        let j = ((y + Self::HALF_WIDTH) / Self::TILE).floor() as i64;
        if (i + j).rem_euclid(2) == 0 {
            DVec3::ONE
        } else {
            DVec3::ZERO
        }
    }

    /// [`Floor::color_at`] for a point known to within `(ex, ey)`: a coordinate within
    /// its error of a tile line (a multiple of [`Floor::TILE`], the floor's edges
    /// included) is taken as on it, and so in the tile above it, as `floor` rules. A
    /// camera with integer, axis-aligned geometry puts whole rows of pixel rays exactly
    /// on tile lines, where the rounding of the hit point would pick either tile.
    pub fn color_at_within(x: f64, y: f64, ex: f64, ey: f64) -> DVec3 {
        let snap = |w: f64, e: f64| {
            let line = (w / Self::TILE).round() * Self::TILE;
            if (w - line).abs() <= e { line } else { w }
        };
        Self::color_at(snap(x, ex), snap(y, ey))
    }

    /// Whether (x, y) lies on the finite floor (inclusive bounds).
    pub fn contains(x: f64, y: f64) -> bool {
        x.abs() <= Self::HALF_WIDTH && y.abs() <= Self::HALF_WIDTH
    }
}

impl Scene {
    /// The scene handed out with the assignment, compiled into the binary.
    pub const GIVEN: &'static str = include_str!("../../scenes/given.txt");

    /// Object `index` (0-based) as messages name it: its keyword and its number among
    /// the objects of that kind in the file ("sphere 2": the file's second sphere).
    pub fn object_name(&self, index: usize) -> String {
        let keyword = |s: &Shape| match s {
            Shape::Sphere { .. } => "sphere",
            Shape::Triangle { .. } => "triangle",
            Shape::Quadric(_) => "general",
            Shape::Prism { .. } => "prism",
            Shape::Mesh(_) => "mesh",
        };
        let kind = keyword(&self.objects[index].shape);
        let n = self.objects[..=index]
            .iter()
            .filter(|o| keyword(&o.shape) == kind)
            .count();
        format!("{kind} {n}")
    }

    /// Parses [`Scene::GIVEN`].
    pub fn given() -> Scene {
        parse_scene(Self::GIVEN, "scenes/given.txt")
            .expect("the embedded scene parses (checked by tests)")
            .scene
    }

    pub fn has_prisms(&self) -> bool {
        self.objects
            .iter()
            .any(|o| matches!(o.shape, Shape::Prism { .. }))
    }
}

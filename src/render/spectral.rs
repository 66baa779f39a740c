//! Spectral light for dispersive (glass) objects: wavelengths, colour matching,
//! Snell's law, Fresnel.
//!
//! Only rays that meet a dispersive object pay for wavelengths. A ray is traced in RGB
//! (as the spec's Phong model has it) until it meets glass; there its transmitted part
//! splits into [`CAMERA_SAMPLES`] monochromatic rays, each refracted with its own index
//! n(λ) = cauchy_a + cauchy_b / λ². Each monochromatic ray carries an RGB colour like any
//! other ray; the colours are summed with per-wavelength RGB weights ([`Wavelengths`])
//! that add up to exactly (1, 1, 1), so light that is not dispersed (flat glass, n
//! constant) comes out with exactly the colour it went in with.
//!
//! Colour matching: the CIE 1931 2° standard observer in the multi-lobe analytic fit of
//! Wyman, Sloan and Shirley, "Simple Analytic Approximations to the CIE XYZ Color
//! Matching Functions", JCGT 2(2), 2013 (their equation 4, a piecewise-Gaussian fit
//! within the observer's own measurement noise), then XYZ → linear sRGB (IEC 61966-2-1,
//! D65). A monochromatic colour lies outside the sRGB gamut; it is clipped by zeroing its
//! negative components (so light never subtracts), then each channel is divided by its
//! mean over 380–720 nm, so a flat (equal-energy) spectrum maps to white (1, 1, 1).
//!
//! Everything here is f64 and pure (no state, no allocation): the reference calls it per
//! ray, and the fast path can call the same functions for its few glass rays.

use glam::DVec3;
use std::sync::OnceLock;

/// Shortest wavelength traced, nanometres.
pub const LAMBDA_MIN_NM: f64 = 380.0;
/// Longest wavelength traced, nanometres.
pub const LAMBDA_MAX_NM: f64 = 720.0;
/// Wavelengths per pixel for camera rays that meet glass: one per stratum of
/// (720 − 380) / 16 = 21.25 nm, jittered per pixel.
pub const CAMERA_SAMPLES: usize = 16;

/// Squared piecewise Gaussian of the Wyman–Sloan–Shirley fit: `lo`/`hi` are the inverse
/// widths below and above the centre `mu`.
fn lobe(lambda: f64, mu: f64, lo: f64, hi: f64) -> f64 {
    let t = (lambda - mu) * if lambda < mu { lo } else { hi };
    (-0.5 * t * t).exp()
}

/// CIE 1931 2° colour matching functions (x̄, ȳ, z̄) at `lambda_nm` (multi-lobe fit of
/// Wyman, Sloan and Shirley 2013).
pub fn cie_xyz(lambda_nm: f64) -> DVec3 {
    let l = lambda_nm;
    let x = 0.362 * lobe(l, 442.0, 0.0624, 0.0374) + 1.056 * lobe(l, 599.8, 0.0264, 0.0323)
        - 0.065 * lobe(l, 501.1, 0.0490, 0.0382);
    let y = 0.821 * lobe(l, 568.8, 0.0213, 0.0247) + 0.286 * lobe(l, 530.9, 0.0613, 0.0322);
    let z = 1.217 * lobe(l, 437.0, 0.0845, 0.0278) + 0.681 * lobe(l, 459.0, 0.0385, 0.0725);
    DVec3::new(x, y, z)
}

/// CIE XYZ → linear sRGB (D65 white), IEC 61966-2-1.
pub fn xyz_to_linear_srgb(c: DVec3) -> DVec3 {
    DVec3::new(
        3.2404542 * c.x - 1.5371385 * c.y - 0.4985314 * c.z,
        -0.9692660 * c.x + 1.8760108 * c.y + 0.0415560 * c.z,
        0.0556434 * c.x - 0.2040259 * c.y + 1.0572252 * c.z,
    )
}

/// Linear sRGB of monochromatic light at `lambda_nm`, gamut-clipped (negative
/// components zeroed), not yet normalised.
pub fn raw_rgb(lambda_nm: f64) -> DVec3 {
    xyz_to_linear_srgb(cie_xyz(lambda_nm)).max(DVec3::ZERO)
}

/// Per-channel mean of [`raw_rgb`] over [380, 720] nm (midpoint rule, 0.1 nm steps).
fn rgb_mean() -> DVec3 {
    static MEAN: OnceLock<DVec3> = OnceLock::new();
    *MEAN.get_or_init(|| {
        let n = 3400;
        let step = (LAMBDA_MAX_NM - LAMBDA_MIN_NM) / n as f64;
        let sum: DVec3 = (0..n)
            .map(|i| raw_rgb(LAMBDA_MIN_NM + (i as f64 + 0.5) * step))
            .sum();
        sum / n as f64
    })
}

/// RGB weight of one wavelength drawn uniformly from [380, 720] nm: its mean over the
/// range is exactly (1, 1, 1), so equal-energy light of RGB colour `c` carried by many
/// wavelengths `λ` with power `c ⊙ spectral_weight(λ)` sums to `c`. Used for photons.
pub fn spectral_weight(lambda_nm: f64) -> DVec3 {
    raw_rgb(lambda_nm) / rgb_mean()
}

/// A wavelength in nanometres → micrometres, the unit of the Cauchy coefficients.
pub fn nm_to_um(lambda_nm: f64) -> f64 {
    lambda_nm * 1e-3
}

// ---------------------------------------------------------------- random numbers

/// SplitMix64's finaliser: a well-mixed 64-bit hash. Every random number of the
/// spectral and caustic code is a hash of (seed, what it is for), so results do not
/// depend on thread count or order.
pub fn hash64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash of several keys (order matters).
pub fn hash_keys(keys: &[u64]) -> u64 {
    keys.iter()
        .fold(0x6A09_E667_F3BC_C908, |h, &k| hash64(h ^ k))
}

/// A uniform number in [0, 1) from a hash (53 random bits).
pub fn unit_from_hash(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Glass branches that could add at most this much to a pixel's colour (their path
/// weight: the product of the branch weights from the camera, times the wavelength's
/// largest RGB weight on monochromatic paths) are not traced: 1/2048 is an eighth of an
/// 8-bit step. Every path uses the same rule.
pub const GLASS_CUTOFF: f64 = 1.0 / 2048.0;

/// Most nested glass branchings followed (each glass hit that branches nests one more).
pub const MAX_GLASS_DEPTH: u32 = 64;

// ---------------------------------------------------------------- per-pixel wavelengths

/// The wavelengths of one pixel's glass rays and their RGB weights: stratified over
/// [380, 720] nm (one per 21.25 nm stratum), jittered inside each stratum by a hash of
/// (pixel, seed). The weights are [`raw_rgb`] normalised so that they sum to exactly
/// (1, 1, 1) per channel in this pixel: a colour that does not depend on the wavelength
/// passes unchanged (`Σ wᵢ ⊙ c = c`), whatever the jitter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wavelengths {
    /// Nanometres.
    pub lambda: [f64; CAMERA_SAMPLES],
    pub weight: [DVec3; CAMERA_SAMPLES],
}

impl Wavelengths {
    /// The wavelengths of pixel (x, y) for `seed`.
    pub fn for_pixel(x: u32, y: u32, seed: u64) -> Wavelengths {
        let base = hash_keys(&[seed, 0x5EC7_0001, ((y as u64) << 32) | x as u64]);
        let width = (LAMBDA_MAX_NM - LAMBDA_MIN_NM) / CAMERA_SAMPLES as f64;
        let mut lambda = [0.0; CAMERA_SAMPLES];
        for (i, l) in lambda.iter_mut().enumerate() {
            let u = unit_from_hash(hash64(base ^ i as u64));
            *l = LAMBDA_MIN_NM + (i as f64 + u) * width;
        }
        Wavelengths::from_lambdas(lambda)
    }

    /// Fixed wavelengths (the centre of each stratum): no jitter.
    pub fn centred() -> Wavelengths {
        let width = (LAMBDA_MAX_NM - LAMBDA_MIN_NM) / CAMERA_SAMPLES as f64;
        Wavelengths::from_lambdas(std::array::from_fn(|i| {
            LAMBDA_MIN_NM + (i as f64 + 0.5) * width
        }))
    }

    /// Weights for the given wavelengths, normalised to sum to (1, 1, 1) per channel.
    pub fn from_lambdas(lambda: [f64; CAMERA_SAMPLES]) -> Wavelengths {
        let raw = lambda.map(raw_rgb);
        let sum: DVec3 = raw.iter().copied().sum();
        // every channel has positive weight over any stratified set (each covers the
        // whole range), but guard the division anyway
        let inv = DVec3::select(sum.cmpgt(DVec3::ZERO), sum.recip(), DVec3::ZERO);
        Wavelengths {
            lambda,
            weight: raw.map(|w| w * inv),
        }
    }
}

// ---------------------------------------------------------------- Snell and Fresnel

/// Mirror direction of unit `d` about unit normal `n` (either orientation).
pub fn reflect(d: DVec3, n: DVec3) -> DVec3 {
    (d - n * (2.0 * d.dot(n))).normalize()
}

/// Snell's law. `d` is the unit incident direction, `n` the unit normal on the incident
/// side (`n · d < 0`), `eta` = n_incident / n_transmitted. `None` on total internal
/// reflection.
pub fn refract(d: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let cos_i = -n.dot(d);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((d * eta + n * (eta * cos_i - cos_t)).normalize())
}

/// Exact Fresnel reflectance of unpolarised light at a dielectric interface (the mean
/// of the s and p reflectances), for the cosine `cos_i` of the incident angle, from a
/// medium of index `n_i` into one of index `n_t`. 1 under total internal reflection.
pub fn fresnel_dielectric(cos_i: f64, n_i: f64, n_t: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_t = n_i / n_t * (1.0 - cos_i * cos_i).max(0.0).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let rs = (n_i * cos_i - n_t * cos_t) / (n_i * cos_i + n_t * cos_t);
    let rp = (n_t * cos_i - n_i * cos_t) / (n_t * cos_i + n_i * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// What happens to a ray of one wavelength at the surface of a glass of index `n_glass`
/// in air (index 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interface {
    /// True when the ray enters the glass (it meets the outside of the surface).
    pub entering: bool,
    /// Mirror direction.
    pub reflected: DVec3,
    /// Fresnel reflectance (1 under total internal reflection).
    pub fresnel: f64,
    /// Refracted direction; `None` under total internal reflection.
    pub transmitted: Option<DVec3>,
}

/// Splits unit direction `d` at a glass surface with unit *outward* geometric normal
/// `n_out` (not flipped towards the ray: the orientation tells entering from leaving).
pub fn glass_interface(d: DVec3, n_out: DVec3, n_glass: f64) -> Interface {
    let entering = d.dot(n_out) < 0.0;
    let (n, n_i, n_t) = if entering {
        (n_out, 1.0, n_glass)
    } else {
        (-n_out, n_glass, 1.0)
    };
    let cos_i = -n.dot(d);
    let transmitted = refract(d, n, n_i / n_t);
    let fresnel = if transmitted.is_some() {
        fresnel_dielectric(cos_i, n_i, n_t)
    } else {
        1.0
    };
    Interface {
        entering,
        reflected: reflect(d, n),
        fresnel,
        transmitted,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_spectrum_weights_average_to_white() {
        // midpoint rule at 1 nm: the mean weight is (1, 1, 1) to the quadrature error
        let n = 340;
        let mean: DVec3 = (0..n)
            .map(|i| spectral_weight(380.0 + i as f64 + 0.5))
            .sum::<DVec3>()
            / n as f64;
        assert!((mean - DVec3::ONE).abs().max_element() < 1e-3, "{mean}");
        // per pixel: exactly one (to rounding), whatever the jitter
        for (x, y) in [(0, 0), (17, 301), (767, 767)] {
            let w = Wavelengths::for_pixel(x, y, 7);
            let s: DVec3 = w.weight.iter().copied().sum();
            assert!((s - DVec3::ONE).abs().max_element() < 1e-12, "{s}");
            for (i, l) in w.lambda.iter().enumerate() {
                let lo = 380.0 + i as f64 * 21.25;
                assert!(*l >= lo && *l < lo + 21.25, "stratum {i}: {l}");
            }
        }
    }

    #[test]
    fn colour_matching_fit_peaks_where_the_cie_observer_does() {
        // CIE 1931 2° table: ȳ(555) = 1.0000, x̄(600) = 1.0622, z̄(445) = 1.7826 (the fit
        // is within about 3 % of the table near the peaks)
        assert!((cie_xyz(555.0).y - 1.0).abs() < 0.03);
        assert!((cie_xyz(600.0).x - 1.0622).abs() < 0.03);
        assert!((cie_xyz(445.0).z - 1.7826).abs() < 0.06);
        // hue order: 650 nm red, 530 nm green, 450 nm blue dominate
        let (r, g, b) = (raw_rgb(650.0), raw_rgb(530.0), raw_rgb(450.0));
        assert!(r.x > r.y && r.x > r.z);
        assert!(g.y > g.x && g.y > g.z);
        assert!(b.z > b.x && b.z > b.y);
    }

    #[test]
    fn snell_at_normal_and_oblique_incidence() {
        let n = DVec3::Z;
        // normal incidence passes straight
        let t = refract(-DVec3::Z, n, 1.0 / 1.5).unwrap();
        assert!((t + DVec3::Z).length() < 1e-15);
        // 45° into n = 1.5: sin θt = sin 45° / 1.5 = 0.471405, θt = 28.1255°
        let d = DVec3::new(1.0, 0.0, -1.0).normalize();
        let t = refract(d, n, 1.0 / 1.5).unwrap();
        let theta_t = t.x.atan2(-t.z).to_degrees();
        assert!((theta_t - 28.125_5).abs() < 1e-3, "{theta_t}");
        // Fresnel at normal incidence: ((1.5 − 1)/(1.5 + 1))² = 0.04
        assert!((fresnel_dielectric(1.0, 1.0, 1.5) - 0.04).abs() < 1e-15);
        // Brewster angle atan(1.5) = 56.31°: Rp = 0, R = Rs / 2
        let cb = 1.5f64.atan().cos();
        let rs = ((cb - 1.5 * (1.0 - 1.0 / 1.5f64.powi(2) * (1.0 - cb * cb)).sqrt())
            / (cb + 1.5 * (1.0 - 1.0 / 1.5f64.powi(2) * (1.0 - cb * cb)).sqrt()))
        .powi(2);
        assert!((fresnel_dielectric(cb, 1.0, 1.5) - rs / 2.0).abs() < 1e-12);
    }

    #[test]
    fn total_internal_reflection_per_wavelength() {
        // crown glass, n(λ) = 1.5046 + 0.0042/λ²: the critical angle asin(1/n) is
        // 41.3658° at 700 nm (n = 1.51317) and 40.7857° at 400 nm (n = 1.53085).
        // A ray inside the glass at 41.0° is totally reflected at 400 nm only.
        let g = crate::scene::Glass {
            kt: 1.0,
            cauchy_a: 1.5046,
            cauchy_b: 0.0042,
        };
        let (n_red, n_violet) = (g.index(0.7), g.index(0.4));
        assert!((n_red - 1.513_171).abs() < 1e-6 && (n_violet - 1.530_85).abs() < 1e-6);
        assert!(((1.0 / n_red).asin().to_degrees() - 41.3658).abs() < 1e-3);
        assert!(((1.0 / n_violet).asin().to_degrees() - 40.7857).abs() < 1e-3);
        let n_out = DVec3::Z; // the glass is below z = 0, the ray leaves upwards
        let at = |deg: f64| {
            let a = deg.to_radians();
            DVec3::new(a.sin(), 0.0, a.cos())
        };
        let red = glass_interface(at(41.0), n_out, n_red);
        let violet = glass_interface(at(41.0), n_out, n_violet);
        assert!(!red.entering && !violet.entering);
        assert!(red.transmitted.is_some() && red.fresnel < 1.0);
        assert!(violet.transmitted.is_none() && violet.fresnel == 1.0);
        // just inside / outside the boundary for each wavelength
        for n in [n_red, n_violet] {
            let crit = (1.0 / n).asin().to_degrees();
            assert!(
                glass_interface(at(crit - 1e-6), n_out, n)
                    .transmitted
                    .is_some()
            );
            assert!(
                glass_interface(at(crit + 1e-6), n_out, n)
                    .transmitted
                    .is_none()
            );
        }
        // leaving at 30°: sin θt = n sin 30°; red 49.1641°, violet 49.9448°
        for (n, expect) in [(n_red, 49.1641), (n_violet, 49.9448)] {
            let t = glass_interface(at(30.0), n_out, n).transmitted.unwrap();
            let theta = t.x.atan2(t.z).to_degrees();
            assert!((theta - expect).abs() < 1e-3, "n {n}: {theta}");
        }
        // the reflected ray mirrors about the surface
        let r = glass_interface(at(41.0), n_out, n_violet).reflected;
        assert!((r - DVec3::new(at(41.0).x, 0.0, -at(41.0).z)).length() < 1e-12);
    }
}

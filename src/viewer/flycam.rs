//! The assignment's fully controllable camera, as pure math: no window, no clock.
//!
//! | key                | motion                                   |
//! |--------------------|------------------------------------------|
//! | Up / Down          | forward / back along `look`              |
//! | Left / Right       | left / right along `right`               |
//! | PageUp / PageDown  | up / down along `up`                     |
//! | 1 / 2              | look left / right (rotate about `up`)    |
//! | 3 / 4              | look up / down (rotate about `right`)    |
//! | 5 / 6              | tilt clockwise / counterclockwise (about `look`) |
//!
//! A **step** is [`STEP_UNITS`] units or [`STEP_DEG`] degrees. Pressing a key applies one
//! whole step at once, so a tap does exactly what the assignment's key press does. A key
//! still held after [`REPEAT_DELAY_S`] keeps moving continuously at [`STEPS_PER_S`]; the
//! motion is integrated over held time, so it does not depend on the frame rate. Shift
//! multiplies steps and rate by [`FAST_MOVE`] for moves and [`FAST_TURN`] for turns.
//!
//! Rotation conventions, with the camera's right-handed frame `right = look × up`: a
//! positive angle about `up` turns `look` towards `−right` (look left); about `right` it
//! turns `look` towards `up` (look up); about `look` it turns `up` towards `right`, which
//! is a clockwise roll as seen from behind the camera (tilt clockwise: the picture turns
//! counterclockwise). Every rotation is followed by Gram–Schmidt re-orthonormalisation, so
//! the frame stays orthonormal to a few ulp after any number of turns.

use glam::DVec3;

use crate::scene::Camera;

/// Distance of one step, in scene units.
pub const STEP_UNITS: f64 = 2.0;
/// Angle of one step, in degrees.
pub const STEP_DEG: f64 = 3.0;
/// How long a key must be held before it starts moving continuously.
pub const REPEAT_DELAY_S: f64 = 0.25;
/// Steps per second while a key is held (after the delay), at the base rate.
pub const STEPS_PER_S: f64 = 20.0;
/// Shift's multiplier for moves.
pub const FAST_MOVE: f64 = 5.0;
/// Shift's multiplier for turns.
pub const FAST_TURN: f64 = 2.0;

/// One of the assignment's twelve camera motions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Motion {
    Forward,
    Backward,
    Left,
    Right,
    Up,
    Down,
    LookLeft,
    LookRight,
    LookUp,
    LookDown,
    TiltClockwise,
    TiltCounterclockwise,
}

impl Motion {
    pub const ALL: [Motion; 12] = [
        Motion::Forward,
        Motion::Backward,
        Motion::Left,
        Motion::Right,
        Motion::Up,
        Motion::Down,
        Motion::LookLeft,
        Motion::LookRight,
        Motion::LookUp,
        Motion::LookDown,
        Motion::TiltClockwise,
        Motion::TiltCounterclockwise,
    ];

    fn index(self) -> usize {
        self as usize
    }

    /// Whether the motion turns the camera (rather than moving its eye).
    pub fn is_turn(self) -> bool {
        self.index() >= Motion::LookLeft.index()
    }

    /// The motion that undoes this one.
    pub fn inverse(self) -> Motion {
        let i = self.index();
        Motion::ALL[i ^ 1]
    }
}

/// Applies `steps` (possibly fractional or negative) steps of `motion` to `camera`.
/// Moves leave `look`, `right` and `up` untouched; turns re-orthonormalise them.
pub fn apply(camera: &mut Camera, motion: Motion, steps: f64) {
    let d = STEP_UNITS * steps;
    let a = (STEP_DEG * steps).to_radians();
    let c = &mut *camera;
    match motion {
        Motion::Forward => c.eye += c.look * d,
        Motion::Backward => c.eye -= c.look * d,
        Motion::Left => c.eye -= c.right * d,
        Motion::Right => c.eye += c.right * d,
        Motion::Up => c.eye += c.up * d,
        Motion::Down => c.eye -= c.up * d,
        Motion::LookLeft => (c.look, c.right) = rotate(c.look, c.right, a),
        Motion::LookRight => (c.look, c.right) = rotate(c.look, c.right, -a),
        Motion::LookUp => (c.look, c.up) = rotate(c.look, -c.up, a).map_second(|u| -u),
        Motion::LookDown => (c.look, c.up) = rotate(c.look, -c.up, -a).map_second(|u| -u),
        Motion::TiltClockwise => (c.up, c.right) = rotate(c.up, -c.right, a).map_second(|r| -r),
        Motion::TiltCounterclockwise => {
            (c.up, c.right) = rotate(c.up, -c.right, -a).map_second(|r| -r)
        }
    }
    if motion.is_turn() {
        orthonormalize(camera);
    }
}

/// Rotates the orthonormal pair (p, q) by `angle` in their plane, turning `p` away from
/// `q`: p' = p cos a − q sin a, q' = q cos a + p sin a.
fn rotate(p: DVec3, q: DVec3, angle: f64) -> (DVec3, DVec3) {
    let (s, c) = angle.sin_cos();
    (p * c - q * s, q * c + p * s)
}

trait MapSecond {
    fn map_second(self, f: impl FnOnce(DVec3) -> DVec3) -> Self;
}

impl MapSecond for (DVec3, DVec3) {
    fn map_second(self, f: impl FnOnce(DVec3) -> DVec3) -> Self {
        (self.0, f(self.1))
    }
}

/// Gram–Schmidt in the order look, right, up: `look` keeps its direction, `right` is made
/// orthogonal to it, and `up = right × look` completes the right-handed frame.
pub fn orthonormalize(camera: &mut Camera) {
    let look = camera.look.normalize();
    let right = (camera.right - look * look.dot(camera.right)).normalize();
    camera.look = look;
    camera.right = right;
    camera.up = right.cross(look);
}

/// Largest deviation of the camera's frame from orthonormal and right-handed: the max of
/// |‖v‖ − 1| over the three vectors, |a·b| over the three pairs and ‖look × up − right‖.
pub fn frame_error(c: &Camera) -> f64 {
    [
        (c.look.length() - 1.0).abs(),
        (c.right.length() - 1.0).abs(),
        (c.up.length() - 1.0).abs(),
        c.look.dot(c.right).abs(),
        c.look.dot(c.up).abs(),
        c.right.dot(c.up).abs(),
        (c.look.cross(c.up) - c.right).length(),
    ]
    .into_iter()
    .fold(0.0, f64::max)
}

/// A camera driven by held keys: [`FlyCam::press`] on a key-down event,
/// [`FlyCam::release`] on key-up, and [`FlyCam::advance`] once per loop iteration with the
/// time elapsed.
#[derive(Clone, Debug)]
pub struct FlyCam {
    pub camera: Camera,
    /// For each motion, how long its key has been held (seconds), or `None`.
    held: [Option<f64>; 12],
}

impl FlyCam {
    pub fn new(camera: Camera) -> FlyCam {
        FlyCam {
            camera,
            held: [None; 12],
        }
    }

    fn multiplier(motion: Motion, fast: bool) -> f64 {
        match (fast, motion.is_turn()) {
            (false, _) => 1.0,
            (true, false) => FAST_MOVE,
            (true, true) => FAST_TURN,
        }
    }

    /// A key went down: one whole step now, and the hold timer starts. A key-down for a
    /// key already held (auto-repeat) is ignored: holding is handled by [`FlyCam::advance`].
    pub fn press(&mut self, motion: Motion, fast: bool) {
        let slot = &mut self.held[motion.index()];
        if slot.is_none() {
            *slot = Some(0.0);
            apply(&mut self.camera, motion, Self::multiplier(motion, fast));
        }
    }

    /// A key went up.
    pub fn release(&mut self, motion: Motion) {
        self.held[motion.index()] = None;
    }

    /// Releases every key (the window lost focus).
    pub fn release_all(&mut self) {
        self.held = [None; 12];
    }

    /// Whether any motion key is held.
    pub fn any_held(&self) -> bool {
        self.held.iter().any(Option::is_some)
    }

    /// Advances held keys by `dt` seconds. A key held for `t` seconds in total has moved
    /// `1 + STEPS_PER_S · max(0, t − REPEAT_DELAY_S)` steps, however the time is sliced.
    /// Returns whether the camera moved.
    pub fn advance(&mut self, dt: f64, fast: bool) -> bool {
        let dt = dt.max(0.0);
        let mut moved = false;
        for motion in Motion::ALL {
            let Some(t) = self.held[motion.index()] else {
                continue;
            };
            let t_new = t + dt;
            let steps =
                STEPS_PER_S * ((t_new - REPEAT_DELAY_S).max(0.0) - (t - REPEAT_DELAY_S).max(0.0));
            self.held[motion.index()] = Some(t_new);
            if steps > 0.0 {
                apply(
                    &mut self.camera,
                    motion,
                    steps * Self::multiplier(motion, fast),
                );
                moved = true;
            }
        }
        moved
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64*: deterministic and dependency-free.
    struct Rng(u64);

    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
        }

        /// Uniform in [0, 1).
        fn unit(&mut self) -> f64 {
            (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    fn camera() -> Camera {
        Camera::default()
    }

    fn angle_deg(a: DVec3, b: DVec3) -> f64 {
        a.normalize()
            .dot(b.normalize())
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }

    #[test]
    fn moves_go_two_units_along_the_right_axis() {
        let c0 = camera();
        let cases = [
            (Motion::Forward, c0.look),
            (Motion::Backward, -c0.look),
            (Motion::Left, -c0.right),
            (Motion::Right, c0.right),
            (Motion::Up, c0.up),
            (Motion::Down, -c0.up),
        ];
        for (motion, dir) in cases {
            let mut c = c0;
            apply(&mut c, motion, 1.0);
            assert!(
                (c.eye - (c0.eye + dir * 2.0)).length() < 1e-12,
                "{motion:?}: {}",
                c.eye
            );
            assert_eq!((c.look, c.right, c.up), (c0.look, c0.right, c0.up));
        }
        // The default camera looks along (−1, −1, 0)/√2: forward decreases x and y.
        let mut c = c0;
        apply(&mut c, Motion::Forward, 1.0);
        assert!(c.eye.x < 100.0 && c.eye.y < 100.0 && c.eye.z == 50.0);
    }

    #[test]
    fn turns_are_three_degrees_in_the_stated_directions() {
        let c0 = camera();
        // (motion, the vector that turns, the vector it turns towards, the fixed axis)
        let cases = [
            (Motion::LookLeft, 0, -c0.right, c0.up),
            (Motion::LookRight, 0, c0.right, c0.up),
            (Motion::LookUp, 0, c0.up, c0.right),
            (Motion::LookDown, 0, -c0.up, c0.right),
            (Motion::TiltClockwise, 2, c0.right, c0.look),
            (Motion::TiltCounterclockwise, 2, -c0.right, c0.look),
        ];
        for (motion, which, towards, axis) in cases {
            let mut c = c0;
            apply(&mut c, motion, 1.0);
            let (before, after) = match which {
                0 => (c0.look, c.look),
                _ => (c0.up, c.up),
            };
            assert!((angle_deg(before, after) - 3.0).abs() < 1e-9, "{motion:?}");
            assert!(
                (after - before).dot(towards) > 0.0,
                "{motion:?} turned the wrong way"
            );
            // The rotation axis is unchanged.
            let axis_after = if axis == c0.up {
                c.up
            } else if axis == c0.right {
                c.right
            } else {
                c.look
            };
            assert!(
                (axis_after - axis).length() < 1e-15,
                "{motion:?} moved its axis"
            );
            assert_eq!(c.eye, c0.eye);
            assert!(frame_error(&c) < 1e-15, "{motion:?}");
        }
        // Thirty steps of look-left is a quarter turn: the default camera, looking along
        // (−1, −1, 0)/√2, ends up looking along −right = (1, −1, 0)/√2.
        let mut c = c0;
        apply(&mut c, Motion::LookLeft, 30.0);
        assert!((angle_deg(c.look, c0.look) - 90.0).abs() < 1e-9);
        assert!((c.look + c0.right).length() < 1e-12, "{}", c.look);
    }

    #[test]
    fn each_motion_is_undone_by_its_inverse() {
        for motion in Motion::ALL {
            let mut c = camera();
            apply(&mut c, motion, 1.7);
            apply(&mut c, motion.inverse(), 1.7);
            let c0 = camera();
            for (a, b) in [
                (c.eye, c0.eye),
                (c.look, c0.look),
                (c.right, c0.right),
                (c.up, c0.up),
            ] {
                assert!((a - b).length() < 1e-12, "{motion:?}");
            }
            assert_eq!(motion.inverse().inverse(), motion);
        }
    }

    #[test]
    fn hundred_thousand_random_turns_stay_orthonormal() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut c = camera();
        let mut worst: f64 = 0.0;
        for _ in 0..100_000 {
            let motion = Motion::ALL[6 + (rng.next_u64() % 6) as usize];
            // Anything from a sliver of a step to a large turn.
            let steps = rng.unit() * 40.0 - 20.0;
            apply(&mut c, motion, steps);
            worst = worst.max(frame_error(&c));
        }
        assert!(worst < 4e-15, "frame error reached {worst}");
        // Moves after all those turns still go exactly along the frame.
        let before = c;
        apply(&mut c, Motion::Forward, 1.0);
        assert!(((c.eye - before.eye).length() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn without_reorthonormalising_the_frame_would_drift() {
        // Guards the test above: the same turns without Gram–Schmidt do drift, so the
        // tolerance there is not vacuous.
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut c = camera();
        for _ in 0..100_000 {
            let axis = (rng.next_u64() % 3) as usize;
            let a = (rng.unit() * 40.0 - 20.0) * STEP_DEG.to_radians();
            match axis {
                0 => (c.look, c.right) = rotate(c.look, c.right, a),
                1 => (c.look, c.up) = rotate(c.look, c.up, a),
                _ => (c.up, c.right) = rotate(c.up, c.right, a),
            }
        }
        assert!(frame_error(&c) > 1e-14, "{}", frame_error(&c));
    }

    #[test]
    fn a_tap_is_exactly_one_step() {
        let mut f = FlyCam::new(camera());
        f.press(Motion::Forward, false);
        f.press(Motion::Forward, false); // auto-repeat key-down: ignored
        assert!(!f.advance(0.1, false));
        f.release(Motion::Forward);
        let mut want = camera();
        apply(&mut want, Motion::Forward, 1.0);
        assert_eq!(f.camera, want);
        assert!(!f.any_held());
    }

    #[test]
    fn held_keys_move_the_same_whatever_the_frame_rate() {
        let hold = |dt: f64, frames: usize| {
            let mut f = FlyCam::new(camera());
            f.press(Motion::Forward, false);
            f.press(Motion::Right, false);
            for _ in 0..frames {
                f.advance(dt, false);
            }
            f.camera.eye
        };
        // One second held: 1 + 20 · 0.75 = 16 steps = 32 units along each axis.
        let slow = hold(1.0 / 7.0, 7);
        let fast = hold(1.0 / 240.0, 240);
        let once = hold(1.0, 1);
        assert!((slow - fast).length() < 1e-9, "{slow} vs {fast}");
        assert!((once - fast).length() < 1e-9, "{once} vs {fast}");
        let c0 = camera();
        let want = c0.eye + c0.look * 32.0 + c0.right * 32.0;
        assert!((fast - want).length() < 1e-9, "{fast} vs {want}");
    }

    #[test]
    fn held_turns_reach_the_same_angle_whatever_the_frame_rate() {
        let turn = |dt: f64, frames: usize| {
            let mut f = FlyCam::new(camera());
            f.press(Motion::LookLeft, false);
            for _ in 0..frames {
                f.advance(dt, false);
            }
            f.camera.look
        };
        let a = turn(1.0 / 13.0, 13);
        let b = turn(1.0 / 200.0, 200);
        assert!((a - b).length() < 1e-12);
        // 16 steps of 3° = 48°.
        assert!((angle_deg(a, camera().look) - 48.0).abs() < 1e-9);
    }

    #[test]
    fn shift_is_faster_and_release_stops() {
        let mut f = FlyCam::new(camera());
        f.press(Motion::Up, true);
        assert!((f.camera.eye.z - (50.0 + 2.0 * FAST_MOVE)).abs() < 1e-12);
        f.release(Motion::Up);
        let z = f.camera.eye.z;
        assert!(!f.advance(1.0, true));
        assert_eq!(f.camera.eye.z, z);

        let mut g = FlyCam::new(camera());
        g.press(Motion::TiltClockwise, true);
        assert!((angle_deg(g.camera.up, DVec3::Z) - 3.0 * FAST_TURN).abs() < 1e-9);
        g.release_all();
        assert!(!g.any_held());
    }
}

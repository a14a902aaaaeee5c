//! glTF animation samplers (glTF 2.0, §3.11 "Animations" and Appendix C
//! "Animation Sampler Interpolation Modes"): a node's translation, rotation
//! or scale as keys in time, played at any time in seconds. Before the
//! first key the first value holds, after the last the last.

use glam::{DQuat, DVec4};

/// How a sampler moves between its keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// The key's value until the next key.
    Step,
    /// Straight lines; rotations by spherical linear interpolation.
    Linear,
    /// Cubic Hermite splines with a tangent on each side of each key.
    CubicSpline,
}

/// One sampler: increasing key times and their values (three per key for
/// a cubic spline: in-tangent, value, out-tangent). Vectors use x, y, z;
/// rotations are quaternions (x, y, z, w).
#[derive(Clone, Debug, PartialEq)]
pub struct Sampler {
    times: Vec<f64>,
    values: Vec<DVec4>,
    interpolation: Interpolation,
    rotation: bool,
}

impl Sampler {
    /// A sampler over `times` (finite, strictly increasing, at least one)
    /// and `values` (one per key, three per key for a cubic spline, every
    /// component finite; a rotation key not zero). The message says what
    /// is wrong, for the caller to place.
    pub fn new(
        times: Vec<f64>,
        values: Vec<DVec4>,
        interpolation: Interpolation,
        rotation: bool,
    ) -> Result<Sampler, String> {
        if times.is_empty() {
            return Err("input: no keys".into());
        }
        if let Some(i) = times.iter().position(|t| !t.is_finite()) {
            return Err(format!("input: time {i} is not finite"));
        }
        if let Some(i) = times.windows(2).position(|w| w[1] <= w[0]) {
            return Err(format!(
                "input: times must increase, but time {} is {:?} after {:?}",
                i + 1,
                times[i + 1],
                times[i]
            ));
        }
        let per_key = match interpolation {
            Interpolation::CubicSpline => 3,
            _ => 1,
        };
        if values.len() != times.len() * per_key {
            return Err(format!(
                "output: {} values for {} keys; {} expects {}",
                values.len(),
                times.len(),
                match interpolation {
                    Interpolation::CubicSpline => "CUBICSPLINE (in-tangent, value, out-tangent)",
                    Interpolation::Linear => "LINEAR",
                    Interpolation::Step => "STEP",
                },
                times.len() * per_key
            ));
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("output: value {i} is not finite"));
        }
        if rotation
            && let Some(k) =
                (0..times.len()).find(|&k| values[k * per_key + per_key / 2] == DVec4::ZERO)
        {
            return Err(format!("output: rotation key {k} is zero, not a rotation"));
        }
        Ok(Sampler {
            times,
            values,
            interpolation,
            rotation,
        })
    }

    /// The value of key `k`.
    fn key(&self, k: usize) -> DVec4 {
        match self.interpolation {
            Interpolation::CubicSpline => self.values[3 * k + 1],
            _ => self.values[k],
        }
    }

    /// The value at time `t` seconds (a rotation normalised). A cubic
    /// spline between rotation keys q and −q (the same rotation) may pass
    /// through the zero quaternion, which is no rotation: there, and
    /// wherever its length is too small to normalise, the nearer key's
    /// rotation holds.
    pub fn at(&self, t: f64) -> DVec4 {
        let last = self.times.len() - 1;
        // The key nearest to `t`, for a rotation that cannot be normalised.
        let mut nearer = 0;
        let v = if t.is_nan() || t <= self.times[0] {
            self.key(0)
        } else if t >= self.times[last] {
            nearer = last;
            self.key(last)
        } else {
            // times[k] <= t < times[k + 1]
            let k = self.times.partition_point(|&x| x <= t) - 1;
            let (t0, t1) = (self.times[k], self.times[k + 1]);
            let s = (t - t0) / (t1 - t0);
            nearer = if s < 0.5 { k } else { k + 1 };
            match self.interpolation {
                Interpolation::Step => self.key(k),
                Interpolation::Linear if self.rotation => slerp(self.key(k), self.key(k + 1), s),
                Interpolation::Linear => self.key(k).lerp(self.key(k + 1), s),
                Interpolation::CubicSpline => {
                    let out_tangent = self.values[3 * k + 2];
                    let in_tangent = self.values[3 * (k + 1)];
                    hermite(
                        self.key(k),
                        out_tangent,
                        self.key(k + 1),
                        in_tangent,
                        t1 - t0,
                        s,
                    )
                }
            }
        };
        if !self.rotation {
            v
        } else if v.length_squared() > ROTATION_FLOOR && v.is_finite() {
            v.normalize()
        } else {
            self.key(nearer).normalize()
        }
    }
}

/// The squared length below which an interpolated rotation is taken as
/// the zero quaternion (no rotation to normalise): far below any rounding
/// of unit keys, far above f64's underflow.
const ROTATION_FLOOR: f64 = 1e-200;

/// Spherical linear interpolation from rotation `a` to `b` along the
/// shorter arc (the specification's slerp), as quaternions (x, y, z, w).
pub fn slerp(a: DVec4, b: DVec4, s: f64) -> DVec4 {
    let (a, b) = (
        DQuat::from_vec4(a).normalize(),
        DQuat::from_vec4(b).normalize(),
    );
    DVec4::from(a.slerp(b, s))
}

/// The cubic Hermite spline of glTF's CUBICSPLINE between keys `v0` and
/// `v1` `td` seconds apart, with `b0` the first key's out-tangent and `a1`
/// the second's in-tangent, at `s` in [0, 1]:
/// (2s³ − 3s² + 1)·v0 + td·(s³ − 2s² + s)·b0 + (−2s³ + 3s²)·v1 + td·(s³ − s²)·a1.
pub fn hermite(v0: DVec4, b0: DVec4, v1: DVec4, a1: DVec4, td: f64, s: f64) -> DVec4 {
    let (s2, s3) = (s * s, s * s * s);
    v0 * (2.0 * s3 - 3.0 * s2 + 1.0)
        + b0 * (td * (s3 - 2.0 * s2 + s))
        + v1 * (-2.0 * s3 + 3.0 * s2)
        + a1 * (td * (s3 - s2))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> DVec4 {
        DVec4::new(x, y, z, 0.0)
    }

    fn close(a: DVec4, b: DVec4) -> bool {
        (a - b).abs().max_element() < 1e-12
    }

    #[test]
    fn step_holds_each_key_until_the_next() {
        let s = Sampler::new(
            vec![0.0, 1.0, 2.0],
            vec![v(1.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(3.0, 0.0, 0.0)],
            Interpolation::Step,
            false,
        )
        .unwrap();
        for (t, x) in [
            (-1.0, 1.0),
            (0.0, 1.0),
            (0.5, 1.0),
            (1.0, 2.0),
            (1.99, 2.0),
            (2.0, 3.0),
            (9.0, 3.0),
        ] {
            assert_eq!(s.at(t), v(x, 0.0, 0.0), "t = {t}");
        }
    }

    #[test]
    fn linear_moves_in_straight_lines_and_holds_the_ends() {
        let s = Sampler::new(
            vec![1.0, 3.0],
            vec![v(0.0, 0.0, 0.0), v(4.0, 2.0, -2.0)],
            Interpolation::Linear,
            false,
        )
        .unwrap();
        assert_eq!(s.at(0.0), v(0.0, 0.0, 0.0));
        assert!(close(s.at(1.5), v(1.0, 0.5, -0.5)));
        assert!(close(s.at(2.0), v(2.0, 1.0, -1.0)));
        assert_eq!(s.at(7.0), v(4.0, 2.0, -2.0));
    }

    #[test]
    fn linear_rotation_is_a_slerp_along_the_shorter_arc() {
        let half = std::f64::consts::FRAC_1_SQRT_2;
        // Identity to 90° about y: half way is 45° about y.
        let s = Sampler::new(
            vec![0.0, 1.0],
            vec![
                DVec4::new(0.0, 0.0, 0.0, 1.0),
                DVec4::new(0.0, half, 0.0, half),
            ],
            Interpolation::Linear,
            true,
        )
        .unwrap();
        // sin and cos of 22.5° and 11.25°.
        let (sa, ca) = (0.382_683_432_365_089_8, 0.923_879_532_511_286_7);
        assert!(close(s.at(0.5), DVec4::new(0.0, sa, 0.0, ca)));
        // A quarter of the way: 22.5°.
        assert!(close(
            s.at(0.25),
            DVec4::new(0.0, 0.195_090_322_016_128_3, 0.0, 0.980_785_280_403_230_4)
        ));
        // The same end written as −q: still the 90° turn the short way,
        // not 270° the long way round.
        let s = Sampler::new(
            vec![0.0, 1.0],
            vec![
                DVec4::new(0.0, 0.0, 0.0, 1.0),
                DVec4::new(0.0, -half, 0.0, -half),
            ],
            Interpolation::Linear,
            true,
        )
        .unwrap();
        let m = s.at(0.5);
        let m = if m.w < 0.0 { -m } else { m };
        assert!(close(m, DVec4::new(0.0, sa, 0.0, ca)));
        // Keys that are not unit length are normalised.
        let s = Sampler::new(
            vec![0.0],
            vec![DVec4::new(0.0, 0.0, 0.0, 2.0)],
            Interpolation::Step,
            true,
        )
        .unwrap();
        assert_eq!(s.at(3.0), DVec4::new(0.0, 0.0, 0.0, 1.0));
    }

    #[test]
    fn cubic_spline_follows_hermite_with_tangents_scaled_by_the_key_gap() {
        // Keys 0 → 0 two seconds apart, out-tangent 1 at the first key, in-tangent 0
        // at the second: at t = 1 (s = 1/2), td·(s³ − 2s² + s)·b0 = 2·(1/8 − 1/2 + 1/2) = 1/4.
        let s = Sampler::new(
            vec![0.0, 2.0],
            vec![
                v(9.0, 9.0, 9.0), // in-tangent of key 0 (unused)
                v(0.0, 0.0, 0.0),
                v(1.0, 0.0, 0.0), // out-tangent of key 0
                v(0.0, 0.0, 0.0), // in-tangent of key 1
                v(0.0, 0.0, 0.0),
                v(9.0, 9.0, 9.0), // out-tangent of key 1 (unused)
            ],
            Interpolation::CubicSpline,
            false,
        )
        .unwrap();
        assert!(close(s.at(1.0), v(0.25, 0.0, 0.0)));
        // s = 1/4: 2·(1/64 − 1/8 + 1/4) = 0.28125.
        assert!(close(s.at(0.5), v(0.28125, 0.0, 0.0)));
        assert_eq!(s.at(-1.0), v(0.0, 0.0, 0.0));
        assert_eq!(s.at(5.0), v(0.0, 0.0, 0.0));
        // Keys 0 → 2 one second apart with both tangents 2 (the speed of the
        // straight line): the spline is the line, 2t.
        let s = Sampler::new(
            vec![0.0, 1.0],
            vec![
                v(0.0, 0.0, 0.0),
                v(0.0, 0.0, 0.0),
                v(2.0, 0.0, 0.0),
                v(2.0, 0.0, 0.0),
                v(2.0, 0.0, 0.0),
                v(0.0, 0.0, 0.0),
            ],
            Interpolation::CubicSpline,
            false,
        )
        .unwrap();
        for t in [0.1, 0.3, 0.5, 0.9] {
            assert!(close(s.at(t), v(2.0 * t, 0.0, 0.0)), "t = {t}");
        }
    }

    #[test]
    fn a_cubic_rotation_through_zero_takes_the_nearer_key() {
        // Keys q and −q (the same half turn about y) with zero tangents:
        // the spline is q·(4s³ − 6s² + 1), exactly zero at s = 1/2.
        let q = DVec4::new(0.0, 1.0, 0.0, 0.0);
        let s = Sampler::new(
            vec![0.0, 1.0],
            vec![DVec4::ZERO, q, DVec4::ZERO, DVec4::ZERO, -q, DVec4::ZERO],
            Interpolation::CubicSpline,
            true,
        )
        .unwrap();
        assert_eq!(s.at(0.5), -q, "the nearer key at the half way point");
        assert_eq!(s.at(0.25), q);
        assert!(s.at(0.4).is_finite() && (s.at(0.4) - q).length() < 1e-12);
    }

    #[test]
    fn hostile_samplers_are_refused_with_the_reason() {
        let one = vec![v(0.0, 0.0, 0.0)];
        let two = vec![v(0.0, 0.0, 0.0); 2];
        let err = |t: Vec<f64>, o: Vec<DVec4>, i, r| Sampler::new(t, o, i, r).unwrap_err();
        assert!(
            err(vec![0.0, 1.0], one.clone(), Interpolation::Linear, false)
                .contains("1 values for 2 keys")
        );
        assert!(
            err(
                vec![0.0, 1.0],
                two.clone(),
                Interpolation::CubicSpline,
                false
            )
            .contains("expects 6")
        );
        assert!(
            err(vec![1.0, 1.0], two.clone(), Interpolation::Linear, false)
                .contains("must increase")
        );
        assert!(
            err(
                vec![0.0, f64::NAN],
                two.clone(),
                Interpolation::Linear,
                false
            )
            .contains("not finite")
        );
        assert!(err(vec![], vec![], Interpolation::Step, false).contains("no keys"));
        assert!(
            err(
                vec![0.0],
                vec![DVec4::new(0.0, f64::NAN, 0.0, 1.0)],
                Interpolation::Step,
                true
            )
            .contains("value 0 is not finite")
        );
        assert!(err(vec![0.0], vec![DVec4::ZERO], Interpolation::Step, true).contains("zero"));
    }
}

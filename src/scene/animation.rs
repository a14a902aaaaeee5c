//! Keyed values: a camera, light or transform value in a scene file may be
//! a list of keys `[{ frame = 0, value = … }, { frame = 47, value = … }]`
//! instead of a value. The scene is built for one frame at a time; a keyed
//! value is interpolated at that frame, linearly between the two keys
//! around it or, with `[animation] interpolation = "smooth"`, with
//! smoothstep easing (zero speed at every key). Before the first key the
//! first value holds, after the last key the last.

use serde::de::{DeserializeOwned, Error};
use serde::{Deserialize, Deserializer};

use super::format::OneOrThree;

/// `[animation]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnimationDesc {
    /// Number of frames: frames 0 to frames − 1.
    pub frames: toml::Spanned<u32>,
    /// Frames per second, for players and the animated picture.
    pub fps: Option<toml::Spanned<f64>>,
    /// `linear` (default) or `smooth`.
    pub interpolation: Option<toml::Spanned<Interpolation>>,
}

/// How keyed values move between keys.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Interpolation {
    /// Straight lines between keys.
    #[default]
    Linear,
    /// Smoothstep easing: 3s² − 2s³ between keys.
    Smooth,
}

/// The animation a scene asks for, checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Animation {
    /// Number of frames.
    pub frames: u32,
    /// Frames per second.
    pub fps: f64,
}

/// A value, or keys to interpolate.
#[derive(Clone, Debug, PartialEq)]
pub enum Animated<T> {
    /// The same in every frame.
    Fixed(T),
    /// Keys in increasing frame order (at least one).
    Keys(Vec<(f64, T)>),
}

/// Values that can be interpolated.
pub trait Lerp: Clone {
    /// (1 − s)·a + s·b.
    fn lerp(a: &Self, b: &Self, s: f64) -> Self;
}

impl Lerp for f64 {
    fn lerp(a: &f64, b: &f64, s: f64) -> f64 {
        a + (b - a) * s
    }
}

impl Lerp for [f64; 3] {
    fn lerp(a: &[f64; 3], b: &[f64; 3], s: f64) -> [f64; 3] {
        [0, 1, 2].map(|i| f64::lerp(&a[i], &b[i], s))
    }
}

impl Lerp for OneOrThree {
    fn lerp(a: &OneOrThree, b: &OneOrThree, s: f64) -> OneOrThree {
        OneOrThree(<[f64; 3]>::lerp(&a.0, &b.0, s))
    }
}

impl<T: Lerp> Animated<T> {
    /// The value at `frame`.
    pub fn at(&self, frame: f64, interpolation: Interpolation) -> T {
        match self {
            Animated::Fixed(v) => v.clone(),
            Animated::Keys(keys) => {
                let after = keys.partition_point(|(f, _)| *f <= frame);
                if after == 0 {
                    return keys[0].1.clone();
                }
                if after == keys.len() {
                    return keys[after - 1].1.clone();
                }
                let ((f0, a), (f1, b)) = (&keys[after - 1], &keys[after]);
                let s = (frame - f0) / (f1 - f0);
                let s = match interpolation {
                    Interpolation::Linear => s,
                    Interpolation::Smooth => s * s * (3.0 - 2.0 * s),
                };
                T::lerp(a, b, s)
            }
        }
    }

    /// Whether the value changes from frame to frame.
    pub fn is_keyed(&self) -> bool {
        matches!(self, Animated::Keys(_))
    }
}

impl<'de, T: DeserializeOwned> Deserialize<'de> for Animated<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let value = toml::Value::deserialize(d)?;
        let keys = match &value {
            toml::Value::Array(items)
                if !items.is_empty() && items.iter().all(|i| i.is_table()) =>
            {
                items
            }
            _ => {
                return value
                    .try_into()
                    .map(Animated::Fixed)
                    .map_err(D::Error::custom);
            }
        };
        let mut out: Vec<(f64, T)> = Vec::with_capacity(keys.len());
        for (i, key) in keys.iter().enumerate() {
            let table = key
                .as_table()
                .ok_or_else(|| D::Error::custom("expected a key table"))?;
            if let Some(extra) = table.keys().find(|k| *k != "frame" && *k != "value") {
                return Err(D::Error::custom(format!(
                    "key {i}: unknown field `{extra}`; a key is {{ frame = F, value = ... }}"
                )));
            }
            let frame = match table.get("frame") {
                Some(toml::Value::Integer(f)) => *f as f64,
                Some(toml::Value::Float(f)) => *f,
                _ => {
                    return Err(D::Error::custom(format!(
                        "key {i}: expected `frame = F`, a frame number"
                    )));
                }
            };
            if !frame.is_finite() || frame.abs() > 1e9 {
                return Err(D::Error::custom(format!(
                    "key {i}: frame {frame} is out of range"
                )));
            }
            if let Some((previous, _)) = out.last()
                && frame <= *previous
            {
                return Err(D::Error::custom(format!(
                    "key {i}: frame {frame} does not follow frame {previous}; keys must be in increasing frame order"
                )));
            }
            let value = table
                .get("value")
                .ok_or_else(|| D::Error::custom(format!("key {i}: expected `value = ...`")))?
                .clone()
                .try_into()
                .map_err(|e| D::Error::custom(format!("key {i}: {e}")))?;
            out.push((frame, value));
        }
        Ok(Animated::Keys(out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize)]
    struct Doc {
        v: Animated<[f64; 3]>,
    }

    fn parse(text: &str) -> Result<Animated<[f64; 3]>, String> {
        toml::from_str::<Doc>(text)
            .map(|d| d.v)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn keys_interpolate_and_hold_at_the_ends() {
        let a =
            parse("v = [{ frame = 0, value = [0, 0, 0] }, { frame = 10, value = [10, 20, -10] }]")
                .unwrap();
        let lin = |f| a.at(f, Interpolation::Linear);
        assert_eq!(lin(-5.0), [0.0, 0.0, 0.0]);
        assert_eq!(lin(2.5), [2.5, 5.0, -2.5]);
        assert_eq!(lin(10.0), [10.0, 20.0, -10.0]);
        assert_eq!(lin(99.0), [10.0, 20.0, -10.0]);
        // Smoothstep: symmetric, slower near the keys.
        assert_eq!(a.at(5.0, Interpolation::Smooth), [5.0, 10.0, -5.0]);
        assert!(a.at(1.0, Interpolation::Smooth)[0] < 1.0);
        assert_eq!(
            parse("v = [1, 2, 3]").unwrap(),
            Animated::Fixed([1.0, 2.0, 3.0])
        );
    }

    #[test]
    fn bad_keys_are_refused_with_a_reason() {
        for (text, want) in [
            (
                "v = [{ frame = 3, value = [0, 0, 0] }, { frame = 1, value = [1, 1, 1] }]",
                "increasing",
            ),
            ("v = [{ frame = 0 }]", "value"),
            ("v = [{ value = [0, 0, 0] }]", "frame"),
            ("v = [{ frame = 0, value = [0, 0] }]", "key 0"),
            (
                "v = [{ frame = 0, value = [0, 0, 0], ease = 1 }]",
                "unknown field `ease`",
            ),
            ("v = [1, 2]", "length"),
        ] {
            let e = parse(text).unwrap_err();
            assert!(e.contains(want), "{text}: {e}");
        }
    }
}

//! The question every closed solid answers for constructive solid
//! geometry: along which intervals of the whole line o + t·d (t from −∞ to
//! +∞) is the point inside? Roth's ray casting (1982) combines these
//! intervals with set operations; see `csg.rs`.
//!
//! An interval is closed, [enter, exit], with the surface at each end:
//! its parameter and which part of the solid's surface it lies on (a
//! box's face, a cone's side or cap). The outward normal there is another
//! question, asked of the solid only for the end that becomes a hit
//! (`Shape::surface_normal`): CSG combines many ends for each ray and
//! keeps one. A half-space reaches to ±∞, where there is no surface.
//! Intervals come in ascending order, disjoint; one of zero length (a ray
//! that only touches the solid) is left out, since it encloses nothing.

use arrayvec::ArrayVec;

/// A point where the line crosses a solid's surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// Line parameter (±∞ for a half-space's open end).
    pub t: f64,
    /// Which part of the surface: what the solid works its normal out
    /// from (a box's face, a cone's side or caps; 0 for smooth solids).
    pub part: u8,
}

impl Surface {
    /// The crossing at `t` of a solid with one smooth surface.
    pub const fn at(t: f64) -> Self {
        Surface { t, part: 0 }
    }

    /// No surface: the open end of a half-space.
    pub const fn at_infinity(t: f64) -> Self {
        Surface { t, part: 0 }
    }
}

/// Where the line is inside a solid: from `enter` to `exit`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Where the line comes in (t may be −∞).
    pub enter: Surface,
    /// Where it goes out (t may be +∞).
    pub exit: Surface,
}

/// The inside intervals of an analytic solid: at most two (a torus).
pub type Intervals = ArrayVec<Interval, 2>;

/// `[enter, exit]` as one interval when it encloses something (t_enter <
/// t_exit); a touch (equal parameters) or an empty range gives none.
pub fn interval(enter: Surface, exit: Surface) -> Option<Interval> {
    (enter.t < exit.t).then_some(Interval { enter, exit })
}

/// The intervals where `f` (any function of t, negative inside) is
/// negative, given every sign change of f along the line in ascending
/// order (`roots`) and whether the line starts inside (at t = −∞): each
/// stretch between consecutive roots is classified by f at its middle, so
/// that a root counted twice or a touch left in cannot invert what
/// follows.
pub fn classify_between_roots(roots: &[f64], inside_at: impl Fn(f64) -> bool) -> Intervals {
    let mut out = Intervals::new();
    let mut open: Option<f64> = None;
    for pair in roots.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        if a >= b {
            continue;
        }
        let inside = inside_at(0.5 * (a + b));
        match (inside, open) {
            (true, None) => open = Some(a),
            (false, Some(start)) => {
                push(&mut out, start, a);
                open = None;
            }
            _ => {}
        }
    }
    if let (Some(start), Some(&last)) = (open, roots.last()) {
        push(&mut out, start, last);
    }
    out
}

fn push(out: &mut Intervals, a: f64, b: f64) {
    if let Some(i) = interval(Surface::at(a), Surface::at(b)) {
        let _ = out.try_push(i);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stretches_are_classified_by_their_middles_not_by_counting() {
        // Inside on (1, 2) and (3, 4); a duplicated root at 3 changes nothing.
        let inside = |t: f64| (1.0..2.0).contains(&t) || (3.0..4.0).contains(&t);
        let got = classify_between_roots(&[1.0, 2.0, 3.0, 3.0, 4.0], inside);
        let ends: Vec<_> = got.iter().map(|i| (i.enter.t, i.exit.t)).collect();
        assert_eq!(ends, [(1.0, 2.0), (3.0, 4.0)]);
        // A touch at 2.5 (a root where f does not change sign) adds nothing.
        let got = classify_between_roots(&[1.0, 2.0, 2.5, 3.0, 4.0], inside);
        assert_eq!(got.len(), 2);
    }

    #[test]
    fn a_touch_is_no_interval() {
        let s = Surface::at(1.0);
        assert!(interval(s, s).is_none());
    }
}

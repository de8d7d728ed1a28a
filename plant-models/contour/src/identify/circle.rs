//! Tables of `(cos a, sin a)` that every frame of a signature fit shares:
//! the fitted contour's points at `n` equally spaced angles and the dense
//! check's samples are at the same angles in every frame (issue 34: their
//! sines and cosines were a tenth of the `contour fit` command). Each
//! table holds what `(a.cos(), a.sin())` gives for the same `a`, computed
//! by the same expression, so a point built from it is the point built
//! from fresh calls, to the bit. Kept per thread (the frames run on
//! rayon's), a few tables each.

use std::cell::RefCell;
use std::f64::consts::TAU;
use std::rc::Rc;

use crate::model::basis::{Axis, AxisKey};
use crate::model::curve::sample_sites;

/// What a table is of.
#[derive(Clone, Copy, PartialEq)]
enum Table {
    /// `a = TAU·k/n`, k in 0..n.
    Turn(usize),
    /// `a = TAU·(t − start)/length` at the axis's `n` sample sites t
    /// ([`sample_sites`]).
    Sites(AxisKey, usize),
}

/// Tables kept per thread; the oldest goes first.
const KEPT: usize = 4;

/// `(cos a, sin a)` at each angle of a table.
type CosSin = Rc<[(f64, f64)]>;

thread_local! {
    static TABLES: RefCell<Vec<(Table, CosSin)>> = const { RefCell::new(Vec::new()) };
}

fn table(which: Table, angles: impl FnOnce() -> Vec<f64>) -> CosSin {
    TABLES.with(|tables| {
        let mut tables = tables.borrow_mut();
        if let Some((_, t)) = tables.iter().find(|(w, _)| *w == which) {
            return Rc::clone(t);
        }
        let t: CosSin = angles().into_iter().map(|a| (a.cos(), a.sin())).collect();
        if tables.len() == KEPT {
            tables.remove(0);
        }
        tables.push((which, Rc::clone(&t)));
        t
    })
}

/// The angle of point `k` of `n` around the turn.
pub(crate) fn turn_angle(k: usize, n: usize) -> f64 {
    TAU * k as f64 / n as f64
}

/// `(cos a, sin a)` at [`turn_angle`]`(k, n)`, k in 0..n.
pub(crate) fn turn(n: usize) -> CosSin {
    table(Table::Turn(n), || {
        (0..n).map(|k| turn_angle(k, n)).collect()
    })
}

/// The angle of a signature axis's site `t`.
pub(crate) fn site_angle(axis: &Axis, t: f64) -> f64 {
    TAU * (t - axis.start) / axis.length()
}

/// `(cos a, sin a)` at the [`site_angle`] of each of `axis`'s `n` sample
/// sites.
pub(crate) fn sites(axis: &Axis, n: usize) -> CosSin {
    table(Table::Sites(axis.key(), n), || {
        sample_sites(axis, n)
            .into_iter()
            .map(|t| site_angle(axis, t))
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tables are the fresh calls' values to the bit, for each `n`
    /// asked for again after others pushed it out, and for several axes.
    #[test]
    fn tables_are_the_fresh_values_to_the_bit() {
        for round in 0..3 {
            for n in [1, 3, 64, 256, 1000, 7] {
                let t = turn(n);
                assert_eq!(t.len(), n);
                for (k, &(c, s)) in t.iter().enumerate() {
                    let a = TAU * k as f64 / n as f64;
                    assert_eq!(
                        (c.to_bits(), s.to_bits()),
                        (a.cos().to_bits(), a.sin().to_bits()),
                        "round {round}, n {n}, k {k}"
                    );
                }
                for knots in [3usize, 16, 40] {
                    let axis = Axis::over(0.0, knots as f64, knots, true).unwrap();
                    let t = sites(&axis, n);
                    let s = sample_sites(&axis, n);
                    for (k, &(c, si)) in t.iter().enumerate() {
                        let a = TAU * (s[k] - axis.start) / axis.length();
                        assert_eq!(
                            (c.to_bits(), si.to_bits()),
                            (a.cos().to_bits(), a.sin().to_bits())
                        );
                    }
                }
            }
        }
    }
}

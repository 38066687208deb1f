//! Summaries of repeated timings: the median and the spread.

use serde::{Deserialize, Serialize};

/// Median, extremes and quartiles of repeated measurements \[ms\].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    /// The median (the mean of the middle two for an even count).
    pub median: f64,
    /// The smallest sample.
    pub min: f64,
    /// The largest sample.
    pub max: f64,
    /// First quartile.
    pub q1: f64,
    /// Third quartile.
    pub q3: f64,
    /// Number of samples.
    pub samples: usize,
}

impl Spread {
    /// The spread of `samples`; `None` when there are none.
    pub fn of(samples: &[f64]) -> Option<Spread> {
        let mut s = samples.to_vec();
        s.sort_by(f64::total_cmp);
        let (first, last) = (*s.first()?, *s.last()?);
        Some(Spread {
            median: quantile(&s, 0.5),
            min: first,
            max: last,
            q1: quantile(&s, 0.25),
            q3: quantile(&s, 0.75),
            samples: s.len(),
        })
    }

    /// This spread scaled by `factor` (e.g. from a run of k steps to one step).
    pub fn scaled(self, factor: f64) -> Spread {
        Spread {
            median: self.median * factor,
            min: self.min * factor,
            max: self.max * factor,
            q1: self.q1 * factor,
            q3: self.q3 * factor,
            samples: self.samples,
        }
    }
}

/// The `p`-quantile of sorted, non-empty `s`, interpolated linearly between samples.
fn quantile(s: &[f64], p: f64) -> f64 {
    let at = p * (s.len() - 1) as f64;
    let (lo, hi) = (at.floor() as usize, at.ceil() as usize);
    s[lo] + (s[hi] - s[lo]) * (at - lo as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_quartiles() {
        let s = Spread::of(&[5.0, 1.0, 3.0, 2.0, 4.0]).unwrap();
        assert_eq!(
            (s.median, s.min, s.max, s.q1, s.q3),
            (3.0, 1.0, 5.0, 2.0, 4.0)
        );
        let even = Spread::of(&[1.0, 2.0, 3.0, 4.0]).unwrap();
        assert_eq!(even.median, 2.5);
        assert_eq!(Spread::of(&[]), None);
        assert_eq!(Spread::of(&[7.0]).unwrap().q3, 7.0);
    }
}

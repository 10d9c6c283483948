//! Parameter sweeps of a plan (`kg plan --sweep NAME=START:END:COUNT`): one task per value
//! of a numeric parameter, evenly spaced, so a family of variants (e.g. the samples of a
//! `motion.family`, one per task) runs on a farm like any other plan.

use std::str::FromStr;

/// Most values one sweep may have.
pub const MAX_SWEEP_VALUES: usize = 10_000;

/// `NAME=START:END:COUNT`: `COUNT` evenly spaced values from `START` to `END` (just `START`
/// when `COUNT` is 1) given to a graph input or `node.param`; `NAME,NAME2=…` gives each value
/// to all of them (a family's sample and the blend that reads it back).
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// Graph input names or `node.param`s, each taking every value.
    pub names: Vec<String>,
    /// First value.
    pub start: f64,
    /// Last value.
    pub end: f64,
    /// Number of values, 1..=[`MAX_SWEEP_VALUES`].
    pub count: usize,
}

impl FromStr for Sweep {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("'{s}' is not NAME=START:END:COUNT (e.g. family.u_from=-0.3:0.3:5)");
        let (name, range) = s.split_once('=').ok_or_else(bad)?;
        let parts: Vec<&str> = range.split(':').collect();
        let [start, end, count] = parts[..] else { return Err(bad()) };
        let number = |t: &str| t.trim().parse::<f64>().ok().filter(|v| v.is_finite());
        let (Some(start), Some(end)) = (number(start), number(end)) else { return Err(bad()) };
        let count: usize = count.trim().parse().map_err(|_| bad())?;
        let names: Vec<String> = name.split(',').map(|n| n.trim().to_string()).collect();
        if names.iter().any(String::is_empty) {
            return Err(format!("'{s}' has an empty name"));
        }
        if count == 0 || count > MAX_SWEEP_VALUES {
            return Err(format!("'{s}': COUNT must lie in 1..={MAX_SWEEP_VALUES}"));
        }
        Ok(Sweep { names, start, end, count })
    }
}

impl Sweep {
    /// The values as the text a `--set` takes: rounded to 12 significant digits, so 0.1
    /// steps read `0.3`, not `0.30000000000000004` (whole numbers print without a point and
    /// so fit integer parameters too).
    pub fn values(&self) -> Vec<String> {
        let step = if self.count > 1 { (self.end - self.start) / (self.count - 1) as f64 } else { 0.0 };
        (0..self.count)
            .map(|i| {
                let v = if i + 1 == self.count && self.count > 1 { self.end } else { self.start + step * i as f64 };
                let rounded: f64 = format!("{v:.11e}").parse().unwrap_or(v);
                // −0 prints as "-0"; a plan should not carry that.
                format!("{}", if rounded == 0.0 { 0.0 } else { rounded })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn sweeps_parse_and_space_their_values_evenly() {
        let s: Sweep = "family.u_from=-0.3:0.3:7".parse().unwrap();
        assert_eq!(s.values(), ["-0.3", "-0.2", "-0.1", "0", "0.1", "0.2", "0.3"]);
        let one: Sweep = "family.u_from, blend.u=40:90:1".parse().unwrap();
        assert_eq!(
            (one.names.as_slice(), one.values()),
            (["family.u_from".to_string(), "blend.u".into()].as_slice(), vec!["40".to_string()])
        );
        let ints: Sweep = "n=1:9:5".parse().unwrap();
        assert_eq!(ints.values(), ["1", "3", "5", "7", "9"]);
        for bad in ["x=1:2", "x=a:2:3", "=0:1:2", "x,=0:1:2", "x=0:1:0", "x=0:NaN:2", "x"] {
            assert!(bad.parse::<Sweep>().is_err(), "{bad}");
        }
    }
}

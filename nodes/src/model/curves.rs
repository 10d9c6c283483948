//! Sampled curves: named scalar channels on one clock, the value of analysis nodes
//! (angular momentum, centre of mass, joint angles, IK residuals) that plots and tests read.

use serde::{Deserialize, Serialize};

/// One named channel: a value per frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurveChannel {
    /// Stable name, e.g. `"L.x"` or `"com.y"`.
    pub name: String,
    /// Unit of the samples, e.g. `"kg·m²/s"`.
    pub unit: String,
    /// One sample per frame; frame `i` sits at `i / fps` seconds.
    pub values: Vec<f64>,
}

/// Channels of equal length sampled at one frame rate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Curves {
    fps: f64,
    frames: usize,
    channels: Vec<CurveChannel>,
}

/// Why a set of curves could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CurvesError {
    /// A channel's length differs from the others'.
    #[error("channel '{name}' has {got} samples, the curves have {expected}")]
    Length {
        /// Channel name.
        name: String,
        /// Samples given.
        got: usize,
        /// Samples every channel must have.
        expected: usize,
    },
    /// A sample is NaN or infinite.
    #[error("channel '{name}' has a non-finite sample at frame {frame}")]
    NotFinite {
        /// Channel name.
        name: String,
        /// First bad frame.
        frame: usize,
    },
}

impl Curves {
    /// Empty curves of `frames` samples at `fps` frames per second.
    pub fn new(fps: f64, frames: usize) -> Self {
        Curves { fps, frames, channels: Vec::new() }
    }

    /// Adds a channel; refuses wrong lengths and non-finite samples so plots and
    /// comparisons never meet NaN.
    pub fn push(&mut self, name: &str, unit: &str, values: Vec<f64>) -> Result<(), CurvesError> {
        if values.len() != self.frames {
            return Err(CurvesError::Length { name: name.into(), got: values.len(), expected: self.frames });
        }
        if let Some(frame) = values.iter().position(|v| !v.is_finite()) {
            return Err(CurvesError::NotFinite { name: name.into(), frame });
        }
        self.channels.push(CurveChannel { name: name.into(), unit: unit.into(), values });
        Ok(())
    }

    /// Frames per second of every channel.
    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// Samples per channel.
    pub fn frame_count(&self) -> usize {
        self.frames
    }

    /// The channels in the order they were added.
    pub fn channels(&self) -> &[CurveChannel] {
        &self.channels
    }

    /// The channel called `name`.
    pub fn channel(&self, name: &str) -> Option<&CurveChannel> {
        self.channels.iter().find(|c| c.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channels_must_match_in_length_and_be_finite() {
        let mut c = Curves::new(30.0, 3);
        c.push("a", "m", vec![1.0, 2.0, 3.0]).unwrap();
        assert!(matches!(c.push("b", "m", vec![1.0]), Err(CurvesError::Length { .. })));
        assert!(matches!(c.push("c", "m", vec![1.0, f64::NAN, 0.0]), Err(CurvesError::NotFinite { frame: 1, .. })));
        assert_eq!(c.channel("a").map(|ch| ch.values[2]), Some(3.0));
        assert_eq!(c.channels().len(), 1);
    }
}

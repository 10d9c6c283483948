//! Length units found in motion files, detection of the unit a skeleton was authored in,
//! and memory sizes as messages print them.

use serde::{Deserialize, Serialize};

/// A length unit a source file may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum LengthUnit {
    /// Metres (glTF, already-scaled BVH).
    Metre,
    /// Decimetres (MakeHuman's BVH and OBJ exports).
    Decimetre,
    /// Centimetres (MotionBuilder, DAZ, Maya exports).
    Centimetre,
    /// Inches.
    Inch,
    /// The CMU mocap unit: 1/0.45 inch ≈ 5.644 cm (CMU FAQ), used by every cgspeed
    /// conversion of the CMU database.
    CmuUnit,
}

impl LengthUnit {
    /// Every unit, in detection preference order.
    pub const ALL: [LengthUnit; 5] =
        [LengthUnit::Metre, LengthUnit::Decimetre, LengthUnit::Centimetre, LengthUnit::Inch, LengthUnit::CmuUnit];

    /// Metres per one of this unit.
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Decimetre => 0.1,
            LengthUnit::Centimetre => 0.01,
            LengthUnit::Inch => 0.0254,
            LengthUnit::CmuUnit => 0.0254 / 0.45,
        }
    }

    /// Short stable name (`"m"`, `"dm"`, `"cm"`, `"in"`, `"cmu"`).
    pub fn name(self) -> &'static str {
        match self {
            LengthUnit::Metre => "m",
            LengthUnit::Decimetre => "dm",
            LengthUnit::Centimetre => "cm",
            LengthUnit::Inch => "in",
            LengthUnit::CmuUnit => "cmu",
        }
    }

    /// Parses a [`LengthUnit::name`].
    pub fn from_name(name: &str) -> Option<LengthUnit> {
        LengthUnit::ALL.into_iter().find(|u| u.name() == name)
    }
}

/// Height a human skeleton's rest pose is assumed to have when guessing its unit (metres).
/// Rest extents of real rigs run from about 1.4 m (CMU, crouched offsets) to 1.9 m.
pub const TYPICAL_HUMAN_EXTENT_M: f64 = 1.6;

/// Guesses the unit of a skeleton whose largest rest-pose extent is `extent` file units:
/// the unit that brings it closest (by ratio) to a human's size. CMU units win over inches
/// for extents near 25 because that is what CMU-derived files (by far the most common BVH
/// in the wild) carry; a non-human rig needs the scale override.
pub fn detect_unit(extent: f64) -> LengthUnit {
    let badness = |u: LengthUnit| (extent * u.metres() / TYPICAL_HUMAN_EXTENT_M).ln().abs();
    LengthUnit::ALL.into_iter().min_by(|a, b| badness(*a).total_cmp(&badness(*b))).unwrap_or(LengthUnit::Metre)
}

/// How a clip's lengths were brought to metres on import.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImportScale {
    /// The unit the file was taken to be in (the detected one unless overridden).
    pub unit: Option<LengthUnit>,
    /// Metres per file unit actually applied.
    pub metres_per_unit: f64,
    /// True when the factor was detected rather than given by the user.
    pub detected: bool,
}

impl ImportScale {
    /// No conversion: the file is in metres by specification (glTF).
    pub const METRES: ImportScale =
        ImportScale { unit: Some(LengthUnit::Metre), metres_per_unit: 1.0, detected: false };
}

/// A memory size for messages: MiB below one GiB, GiB above, one decimal.
pub fn memory_size(bytes: f64) -> String {
    const MIB: f64 = (1u64 << 20) as f64;
    if bytes < 1024.0 * MIB { format!("{:.1} MiB", bytes / MIB) } else { format!("{:.1} GiB", bytes / (1024.0 * MIB)) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detects_the_corpus_units_from_their_extents() {
        // Rest extents listed in shared/data/README.md.
        assert_eq!(detect_unit(25.0), LengthUnit::CmuUnit);
        assert_eq!(detect_unit(152.0), LengthUnit::Centimetre);
        assert_eq!(detect_unit(157.0), LengthUnit::Centimetre);
        assert_eq!(detect_unit(64.0), LengthUnit::Inch);
        assert_eq!(detect_unit(16.5), LengthUnit::Decimetre);
        assert_eq!(detect_unit(1.37), LengthUnit::Metre);
    }

    #[test]
    fn names_round_trip() {
        for u in LengthUnit::ALL {
            assert_eq!(LengthUnit::from_name(u.name()), Some(u));
        }
    }
}

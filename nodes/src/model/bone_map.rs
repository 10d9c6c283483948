//! Bone maps: which joint of one skeleton drives which joint of another. The RON file they
//! are saved as is read and written by `crate::formats::bone_map`.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// Target joint name → the source joint whose motion it takes, sorted by target name.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoneMap {
    /// Target joint name → source joint name.
    pub joints: BTreeMap<String, String>,
}

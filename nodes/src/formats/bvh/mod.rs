//! BVH (Biovision Hierarchy) motion files: our own reader and writer.
//!
//! Real files mix 3- and 6-channel joints, put translation channels on non-roots, carry
//! junk before `HIERARCHY`, use any line ending and any frame time, so the reader is
//! deliberately lenient about layout and strict about data.
//!
//! Convention: a joint's local transform is `T(t) · R`, with `R` the rotation channels
//! multiplied in written order (degrees in the file) and `t` the OFFSET with each axis that
//! has a position channel *replaced* by that channel's value. Position channels are
//! absolute: MotionBuilder/HumanIK exports write the first frame's root position as the
//! root OFFSET, so adding the two would double it (hips at 2 m); the independent reference
//! positions in the corpus agree.

mod frames;
mod numbers;
mod reader;
mod writer;

pub use reader::{BvhReadOptions, BvhStats, read_bvh, read_bvh_file};
pub use writer::{BvhUnit, BvhWriteOptions, is_end_site, write_bvh, write_bvh_file, write_bvh_to, write_bvh_with};

//! BVH (Biovision Hierarchy) motion files: our own reader and writer.
//!
//! Real files mix 3- and 6-channel joints, put translation channels on non-roots, carry
//! junk before `HIERARCHY`, use any line ending and any frame time, so the reader is
//! deliberately lenient about layout and strict about data. Convention (as every major
//! implementation): a joint's local transform is `T(offset + position channels) · R`, with
//! `R` the rotation channels multiplied in written order, angles in degrees.

mod reader;
mod writer;

pub use reader::{BvhReadOptions, BvhStats, read_bvh, read_bvh_file};
pub use writer::{write_bvh, write_bvh_file};

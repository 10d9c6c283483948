//! The transition graph of Peng et al. 2007 and what it is made of: pose features and
//! their distance, the two-pass frame clustering, the graph of clusters and the K-best
//! candidate paths. A kernel because [`Clusters`] and [`TransitionGraph`] travel on the
//! graph's edges (the contract's `Value` holds them) while the transitions family builds
//! and plays them.

pub mod cluster;
pub mod distance;
pub mod graph;
pub mod paths;

pub use cluster::Clusters;
pub use graph::TransitionGraph;

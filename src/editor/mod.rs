//! The node editor.
//!
//! - [`commands`]: the pure command reducer over the [`Graph`](crate::graph::Graph)
//!   with undo/redo; widgets only ever emit its commands.
//! - [`fragment`]: copy and paste of graph fragments as graph-file text.
//! - [`collapse`]: a selection collapsed into a subgraph file and the node using it.
//! - [`worker`]: the evaluation thread that owns the engine; stale results are dropped by
//!   request id.
//!
//! Both compile without egui. With the `editor` feature (default on), the egui app behind
//! `kg edit` lives here too; nothing outside this module names egui or eframe.

pub mod collapse;
pub mod commands;
pub mod fragment;
pub mod worker;

#[cfg(feature = "editor")]
mod app;
#[cfg(feature = "editor")]
mod canvas;
#[cfg(feature = "editor")]
pub mod files;
#[cfg(feature = "editor")]
mod panel;
#[cfg(feature = "editor")]
mod results;
#[cfg(feature = "editor")]
mod viewport;

#[cfg(feature = "editor")]
pub use app::{EditorApp, StartError, run};
#[cfg(feature = "editor")]
pub use results::Band;
#[cfg(feature = "editor")]
pub use viewport::SmokeDrawn;

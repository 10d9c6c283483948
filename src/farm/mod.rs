//! Beyond one machine: plans of many graph runs, the per-task reports that make a retry
//! idempotent, and submission files for the farm engines studios already run (Slurm,
//! Kubernetes, Open Job Description, OpenCue). kinegraph never schedules or submits by
//! itself (DESIGN §7).

pub mod attempt;
pub mod emit;
pub mod inputs;
pub mod plan;
pub mod planner;
pub mod report;
pub mod sweep;

pub use emit::{EmitOptions, Target, emit};
pub use plan::{Dependency, HashedFile, Plan, PlanError, Task};
pub use report::{Summary, TaskReport, TaskStatus, merge};

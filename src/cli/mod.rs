//! The `kg` command line: one evaluator, many ways in.
//!
//! Exit codes: 0 success; 1 a node failed (or a regression test did not match); 2 the
//! graph or the command line is invalid.

mod batch;
mod catalogue;
mod inspect;
mod regression;
mod run;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub use run::{Setting, apply_settings, convert_graph, load_graph};

/// Exit code: a node failed.
pub const EXIT_FAILED: u8 = 1;
/// Exit code: the graph or the command line is invalid.
pub const EXIT_INVALID: u8 = 2;

/// kinegraph's headless runner.
#[derive(Parser, Debug)]
#[command(
    name = "kg",
    version,
    about = "Run, check, test and batch kinegraph animation graphs",
    propagate_version = true
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run a graph: evaluate what its sinks need and write its exports into --out.
    Run {
        /// The graph file (.ron).
        graph: PathBuf,
        /// Override a graph input or a node parameter: NAME=VALUE or node.param=VALUE.
        #[arg(long = "set", value_name = "NAME=VALUE")]
        set: Vec<Setting>,
        /// Output folder for exports.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Print one JSON report object on stdout.
        #[arg(long)]
        json: bool,
        /// Worker threads (default: one per core).
        #[arg(long)]
        threads: Option<usize>,
        /// Evaluate only these nodes (and what they need); default: every sink.
        #[arg(long = "target", value_name = "NODE")]
        targets: Vec<String>,
    },
    /// Validate graphs without running them; report every problem.
    Check {
        /// Graph files.
        #[arg(required = true)]
        graphs: Vec<PathBuf>,
        /// Print a JSON array of results.
        #[arg(long)]
        json: bool,
    },
    /// List the node catalogue.
    Nodes {
        /// As a JSON array of node schemas.
        #[arg(long, conflicts_with = "markdown")]
        json: bool,
        /// As Markdown.
        #[arg(long)]
        markdown: bool,
    },
    /// Describe a motion or mesh file: joints, frames, rate, units, meshes, skins.
    Inspect {
        /// A .bvh, .gltf, .glb or .obj file.
        file: PathBuf,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Convert a clip between formats (BVH, glTF/GLB → BVH or GLB) through the engine.
    Convert {
        /// Input clip (.bvh, .gltf, .glb).
        input: PathBuf,
        /// Output file (.bvh or .glb).
        output: PathBuf,
        /// Loader parameters, e.g. --set metres_per_unit=0.01.
        #[arg(long = "set", value_name = "NAME=VALUE")]
        set: Vec<Setting>,
    },
    /// Run a graph once per input file matching a glob, continuing past failures.
    Batch {
        /// The graph file.
        graph: PathBuf,
        /// NAME=GLOB: the graph input (or node.param) to set to each matching file.
        #[arg(long, value_name = "NAME=GLOB")]
        input: Setting,
        /// Output folder; each run writes into a subfolder named after its input file.
        #[arg(long)]
        out: PathBuf,
        /// Runs at the same time (default: one per core).
        #[arg(long)]
        jobs: Option<usize>,
        /// Further overrides applied to every run.
        #[arg(long = "set", value_name = "NAME=VALUE")]
        set: Vec<Setting>,
        /// Print the JSON report on stdout instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// Rewrite graph files in canonical form (sorted, current version; migrates old files).
    Fmt {
        /// Graph files.
        #[arg(required = true)]
        graphs: Vec<PathBuf>,
        /// Only report files that are not in canonical form (exit 1 if any).
        #[arg(long)]
        check: bool,
    },
    /// Open the node editor on a graph (or an empty one).
    #[cfg(feature = "editor")]
    Edit {
        /// The graph file (.ron).
        graph: Option<PathBuf>,
    },
    /// Regression-test saved graphs against their NAME.expect.ron files.
    Test {
        /// Graph files (default: every graph in ./graphs).
        graphs: Vec<PathBuf>,
        /// Rewrite the expectations from this run instead of comparing.
        #[arg(long)]
        bless: bool,
    },
}

/// Runs `kg` with the process arguments.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let code = match cli.command {
        Command::Run { graph, set, out, json, threads, targets } => {
            run::run_command(&graph, &set, &out, json, threads, targets)
        }
        Command::Check { graphs, json } => run::check_command(&graphs, json),
        Command::Nodes { json, markdown } => catalogue::nodes_command(json, markdown),
        Command::Inspect { file, json } => inspect::inspect_command(&file, json),
        Command::Convert { input, output, set } => run::convert_command(&input, &output, &set),
        Command::Batch { graph, input, out, jobs, set, json } => {
            batch::batch_command(&graph, &input, &out, jobs, &set, json)
        }
        Command::Fmt { graphs, check } => run::fmt_command(&graphs, check),
        Command::Test { graphs, bless } => regression::test_command(graphs, bless),
        #[cfg(feature = "editor")]
        Command::Edit { graph } => match crate::editor::run(graph) {
            Ok(()) => 0,
            Err(e) => {
                eprintln!("error: {e}");
                EXIT_FAILED
            }
        },
    };
    ExitCode::from(code)
}

//! The `kg` command line: one evaluator, many ways in.
//!
//! Exit codes: 0 success; 1 a node failed (or a regression test did not match); 2 the
//! graph or the command line is invalid; 3 the output folder (or the farm task) is in use
//! by another kg; 130 the run was cancelled (Ctrl-C, SIGINT, SIGTERM or SIGHUP): what ran
//! is reported, nothing half-written is left.

/// Writes to standard output through [`write_stdout`], like `print!`.
macro_rules! out {
    ($($arg:tt)*) => { $crate::cli::write_stdout(format_args!($($arg)*)) };
}

/// Writes a line to standard output through [`write_stdout`], like `println!`.
macro_rules! outln {
    ($($arg:tt)*) => { $crate::cli::write_stdout(format_args!("{}\n", format_args!($($arg)*))) };
}

/// Writes to standard error through [`write_stderr`], like `eprint!`.
macro_rules! err {
    ($($arg:tt)*) => { $crate::cli::write_stderr(format_args!($($arg)*)) };
}

/// Writes a line to standard error through [`write_stderr`], like `eprintln!`.
macro_rules! errln {
    ($($arg:tt)*) => { $crate::cli::write_stderr(format_args!("{}\n", format_args!($($arg)*))) };
}

mod batch;
mod catalogue;
mod emit;
mod inspect;
mod merge;
mod plan;
mod run;
mod task;
mod test;
mod watch;

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Parser, Subcommand};

use crate::engine::{DEFAULT_MAX_BYTES, DiskCache, Engine, parse_memory_size};

pub use run::{Setting, convert_graph};

/// Exit code: a node failed.
pub const EXIT_FAILED: u8 = 1;
/// Exit code: the graph or the command line is invalid.
pub const EXIT_INVALID: u8 = 2;

/// Exit code: the run was cancelled by a signal (SIGINT, SIGTERM, SIGHUP).
pub const EXIT_CANCELLED: u8 = 130;

/// Exit code: the output folder (or, for a farm task, the task) is in use by another kg;
/// nothing was done.
pub const EXIT_BUSY: u8 = 3;

use crate::output::save_file;

/// Writes to standard output for `out!` and `outln!`. A closed pipe (`kg nodes | head`)
/// is not an error: the rest of the output is dropped and the command ends with the exit
/// code it decides (0 for a listing), where `println!` would panic (exit 101).
pub fn write_stdout(args: std::fmt::Arguments<'_>) {
    use std::io::Write;
    static CLOSED: AtomicBool = AtomicBool::new(false);
    if CLOSED.load(Ordering::Relaxed) {
        return;
    }
    let mut stdout = std::io::stdout().lock();
    if let Err(e) = stdout.write_fmt(args).and_then(|()| stdout.flush()) {
        CLOSED.store(true, Ordering::Relaxed);
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            errln!("warning: cannot write to standard output: {e}");
        }
    }
}

/// Writes to standard error for `err!` and `errln!`. A closed pipe (`kg run … 2>&1 |
/// head`) drops the messages: the command still ends with its own exit code, where
/// `eprintln!` would panic (exit 101) half way through writing outputs.
pub fn write_stderr(args: std::fmt::Arguments<'_>) {
    use std::io::Write;
    let _ = std::io::stderr().lock().write_fmt(args);
}

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
    /// With --plan and --task-index: run one task of a plan (`kg plan`), idempotently.
    Run {
        /// The graph file (.ron); optional with --plan (then it must be the plan's graph).
        #[arg(required_unless_present = "plan")]
        graph: Option<PathBuf>,
        /// Override a graph input or a node parameter: NAME=VALUE or node.param=VALUE.
        #[arg(long = "set", value_name = "NAME=VALUE", conflicts_with = "plan")]
        set: Vec<Setting>,
        /// A plan file from `kg plan`: run the task --task-index of it.
        #[arg(long, requires = "task_index")]
        plan: Option<PathBuf>,
        /// The task to run (0-based; the farm's array index).
        #[arg(long, requires = "plan")]
        task_index: Option<usize>,
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
        #[arg(long = "target", value_name = "NODE", conflicts_with = "plan")]
        targets: Vec<String>,
        #[command(flatten)]
        engine: EngineArgs,
    },
    /// Plan a farm run: one task per input binding and sweep point, with content hashes, as a plan file.
    Plan {
        /// The graph file.
        graph: PathBuf,
        /// NAME=GLOB: a graph input (or node.param) bound to each matching file; several
        /// --input give every combination. NAME=@PLAN binds each output of an upstream
        /// plan's tasks instead, and each task depends on the task making its file.
        #[arg(long, value_name = "NAME=GLOB")]
        input: Vec<Setting>,
        /// NAME=START:END:COUNT: a numeric graph input or node.param swept over COUNT evenly
        /// spaced values, one task each; NAME,NAME2=… gives each value to all of them; several
        /// --sweep give every combination (with every --input binding), e.g. the samples of a
        /// motion.family grid, one per task.
        #[arg(long, value_name = "NAME=START:END:COUNT")]
        sweep: Vec<crate::farm::sweep::Sweep>,
        /// The output root the upstream plan's tasks write into (for NAME=@PLAN).
        #[arg(long, default_value = "out")]
        upstream_out: PathBuf,
        /// Overrides applied to every task (input files among them are hashed).
        #[arg(long = "set", value_name = "NAME=VALUE")]
        set: Vec<Setting>,
        /// The plan file to write.
        #[arg(long)]
        out: PathBuf,
    },
    /// Write the submission file for a farm engine from a plan (never submits).
    Emit(emit::EmitArgs),
    /// Collect the task reports of a plan's run into one summary.
    Merge {
        /// The plan file.
        plan: PathBuf,
        /// The output root the tasks ran into.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Where to save the summary (default: OUT/summary.json).
        #[arg(long)]
        summary: Option<PathBuf>,
        /// Print the summary JSON on stdout instead of the table.
        #[arg(long)]
        json: bool,
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
        /// A .bvh, .gltf, .glb, .fbx or .obj file.
        file: PathBuf,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Convert a clip between formats (BVH, glTF/GLB, FBX → BVH or GLB) through the engine.
    Convert {
        /// Input clip (.bvh, .gltf, .glb, .fbx).
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
        #[command(flatten)]
        engine: EngineArgs,
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
        #[command(flatten)]
        engine: EngineArgs,
    },
    /// Run a graph, then again on every change to it or to the files it reads (only what
    /// the change reaches is recomputed); Ctrl-C stops.
    Watch {
        /// The graph file.
        graph: PathBuf,
        /// Override a graph input or a node parameter: NAME=VALUE or node.param=VALUE.
        #[arg(long = "set", value_name = "NAME=VALUE")]
        set: Vec<Setting>,
        /// Output folder for exports.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Print one JSON report object per run on stdout.
        #[arg(long)]
        json: bool,
        /// Worker threads (default: one per core).
        #[arg(long)]
        threads: Option<usize>,
        #[command(flatten)]
        engine: EngineArgs,
    },
    /// Regression-test saved graphs against their NAME.expect.ron files.
    Test {
        /// Graph files (default: every graph in --root); expectation files are skipped.
        graphs: Vec<PathBuf>,
        /// The folder of graphs to test when none are named (default: ./graphs).
        #[arg(long)]
        root: Option<PathBuf>,
        /// Rewrite the expectations from this run instead of comparing.
        #[arg(long)]
        bless: bool,
    },
}

/// The engine options of the commands that run graphs: the cache folder and the memory
/// limit.
#[derive(clap::Args, Debug, Clone)]
struct EngineArgs {
    /// Keep node results in this folder and serve unchanged nodes from it in later runs
    /// (also across processes: batch jobs and farm tasks can share one).
    #[arg(long, value_name = "DIR")]
    cache: Option<PathBuf>,
    /// Size bound of the cache folder in MiB; the least recently used results go first.
    #[arg(long, value_name = "MIB", default_value_t = DEFAULT_MAX_BYTES >> 20, requires = "cache")]
    cache_max_mib: u64,
    /// Memory one node may plan to use (e.g. 8G, 512M; a bare number is MiB). A node
    /// whose params or inputs ask for more is refused with the param to change. Default:
    /// 80 % of the machine's memory.
    #[arg(long, value_name = "SIZE", value_parser = parse_memory_size)]
    max_memory: Option<u64>,
}

impl EngineArgs {
    /// Runs `command` with an engine over the built-in nodes, with the memory limit and the
    /// cache folder when given; an unusable folder is reported and gives the exit code
    /// instead.
    fn run(&self, command: impl FnOnce(Engine) -> u8) -> u8 {
        let mut engine = Engine::new(kinegraph_nodes::builtin::registry());
        if let Some(bytes) = self.max_memory {
            engine = engine.with_memory_limit(bytes);
        }
        let Some(dir) = &self.cache else { return command(engine) };
        match DiskCache::open(dir, self.cache_max_mib.saturating_mul(1 << 20)) {
            Ok(disk) => command(engine.with_disk_cache(disk)),
            Err(e) => {
                errln!("--cache: {e}");
                EXIT_INVALID
            }
        }
    }
}

/// Runs `kg` with the process arguments.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let code = match cli.command {
        Command::Run { graph, set, plan, task_index, out, json, threads, targets, engine } => {
            match (plan, task_index, graph) {
                (Some(plan), Some(index), graph) => {
                    engine.run(|engine| task::task_command(&plan, index, graph.as_deref(), &out, threads, json, engine))
                }
                (_, _, Some(graph)) => {
                    engine.run(|engine| run::run_command(&graph, &set, &out, json, threads, targets, engine))
                }
                _ => {
                    errln!("kg run: give a GRAPH, or --plan and --task-index");
                    EXIT_INVALID
                }
            }
        }
        Command::Plan { graph, input, sweep, upstream_out, set, out } => {
            plan::plan_command(&graph, &input, &sweep, &set, &upstream_out, &out)
        }
        Command::Emit(args) => emit::emit_command(&args),
        Command::Merge { plan, out, summary, json } => merge::merge_command(&plan, &out, summary.as_deref(), json),
        Command::Check { graphs, json } => run::check_command(&graphs, json),
        Command::Nodes { json, markdown } => catalogue::nodes_command(json, markdown),
        Command::Inspect { file, json } => inspect::inspect_command(&file, json),
        Command::Convert { input, output, set } => run::convert_command(&input, &output, &set),
        Command::Batch { graph, input, out, jobs, set, json, engine } => {
            engine.run(|engine| batch::batch_command(&graph, &input, &out, jobs, &set, json, engine))
        }
        Command::Fmt { graphs, check } => run::fmt_command(&graphs, check),
        Command::Watch { graph, set, out, json, threads, engine } => {
            engine.run(|engine| watch::watch_command(&graph, &set, &out, json, threads, engine))
        }
        Command::Test { graphs, root, bless } => test::test_command(graphs, root.as_deref(), bless),
        #[cfg(feature = "editor")]
        Command::Edit { graph, engine } => engine.run(|engine| match crate::editor::run(graph, engine) {
            Ok(()) => 0,
            Err(e) => {
                errln!("error: {e}");
                EXIT_FAILED
            }
        }),
    };
    ExitCode::from(code)
}

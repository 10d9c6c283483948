//! `kg emit`: the submission file for a farm engine, from a plan. Never submits.

use std::path::{Path, PathBuf};

use super::{EXIT_INVALID, save_file};
use crate::farm::plan::normalised_absolute;
use crate::farm::{EmitOptions, Plan, Target, emit};

/// The `kg emit` options, as typed.
#[derive(clap::Args, Debug)]
pub struct EmitArgs {
    /// The farm engine.
    #[arg(value_enum)]
    pub target: Target,
    /// The plan file.
    pub plan: PathBuf,
    /// Write the submission file here (default: stdout).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Output root the tasks write into (`kg run --plan … --out`), relative to here.
    #[arg(long, default_value = "out")]
    pub run_out: PathBuf,
    /// Folder the tasks run in, on shared storage (default: the current folder).
    #[arg(long)]
    pub workdir: Option<PathBuf>,
    /// The `kg` executable as the farm hosts see it (default: this kg; `kg` for k8s).
    #[arg(long)]
    pub kg: Option<String>,
    /// Job name (default: kg-<graph file stem>).
    #[arg(long)]
    pub name: Option<String>,
    /// Cores per task (also `--threads` of each run).
    #[arg(long, default_value_t = 1)]
    pub cores: u32,
    /// Memory per task, MiB.
    #[arg(long)]
    pub memory_mib: Option<u64>,
    /// At most this many tasks at once.
    #[arg(long)]
    pub max_parallel: Option<usize>,
    /// Retries per task, where the engine retries by itself (k8s, OpenCue).
    #[arg(long, default_value_t = 2)]
    pub retries: u32,
    /// Kubernetes: container image with kg.
    #[arg(long, default_value = "kinegraph:latest")]
    pub image: String,
    /// Kubernetes: PersistentVolumeClaim mounted at the workdir.
    #[arg(long, default_value = "kinegraph-work")]
    pub volume_claim: String,
    /// OpenCue: show.
    #[arg(long, default_value = "kinegraph")]
    pub show: String,
    /// OpenCue: shot (default: the job name).
    #[arg(long)]
    pub shot: Option<String>,
    /// OpenCue: user (default: $USER).
    #[arg(long)]
    pub user: Option<String>,
}

/// The options an emitter needs: every path absolute (typed paths are relative to the
/// current folder), so the tasks find the plan and the output root whatever folder the
/// engine starts them in.
fn options(args: &EmitArgs, plan: &Plan) -> EmitOptions {
    let workdir = normalised_absolute(args.workdir.as_deref().unwrap_or(Path::new(".")));
    let absolute = |p: &Path| normalised_absolute(p).to_string_lossy().into_owned();
    let stem = Path::new(&plan.graph.path).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = args.name.clone().unwrap_or_else(|| format!("kg-{stem}"));
    let this_kg = || std::env::current_exe().map(|p| p.to_string_lossy().into_owned()).unwrap_or_else(|_| "kg".into());
    EmitOptions {
        kg: args.kg.clone().unwrap_or_else(|| if args.target == Target::K8s { "kg".into() } else { this_kg() }),
        plan: absolute(&args.plan),
        out: absolute(&args.run_out),
        workdir: workdir.to_string_lossy().into_owned(),
        shot: args.shot.clone().unwrap_or_else(|| name.clone()),
        name,
        cores: args.cores.max(1),
        memory_mib: args.memory_mib,
        max_parallel: args.max_parallel,
        retries: args.retries,
        image: args.image.clone(),
        volume_claim: args.volume_claim.clone(),
        show: args.show.clone(),
        user: args.user.clone().or_else(|| std::env::var("USER").ok()).unwrap_or_else(|| "kinegraph".into()),
    }
}

/// Writes (or prints) the submission file.
pub(super) fn emit_command(args: &EmitArgs) -> u8 {
    let plan = match Plan::read(&args.plan) {
        Ok(p) => p,
        Err(e) => {
            errln!("{e}");
            return EXIT_INVALID;
        }
    };
    let text = match emit(args.target, &plan, &options(args, &plan)) {
        Ok(t) => t,
        Err(e) => {
            errln!("{}: {e}", args.plan.display());
            return EXIT_INVALID;
        }
    };
    match &args.out {
        None => {
            out!("{text}");
            0
        }
        Some(path) => match save_file(path, text.as_bytes()) {
            Ok(()) => {
                errln!("{}: {} tasks for {}", path.display(), plan.tasks.len(), args.target.name());
                0
            }
            Err(e) => {
                errln!("{e}");
                EXIT_INVALID
            }
        },
    }
}

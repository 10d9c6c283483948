//! Trains the learned pre-condition of a physics controller (kernels::physics::learned) on
//! trials of the CMU 02_01 figure, reports its accuracy on fresh held-out trials next to the
//! hand-written pre-condition's, and writes the model as RON.
//!
//! `cargo run --release -p kinegraph-nodes --example learn_precondition -- CONTROLLER
//! TRAIN_TRIALS HELD_OUT_TRIALS SEED OUT.ron` (the shared data corpus is found as the tests
//! find it, or through `KG_SHARED_DATA`). Training trials are `0..TRAIN_TRIALS` of `SEED`,
//! the held-out ones the next `HELD_OUT_TRIALS`.

use std::process::ExitCode;
use std::sync::Arc;

use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::atomic::write_atomic;
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::kernels::physics::learned::{sample_trials, train};
use kinegraph_nodes::kernels::physics::simulate::SimParams;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [controller, trials, held_out, seed, out] = args.as_slice() else {
        eprintln!("usage: learn_precondition CONTROLLER TRAIN_TRIALS HELD_OUT_TRIALS SEED OUT.ron");
        return ExitCode::from(2);
    };
    let (Ok(trials), Ok(held_out), Ok(seed)) = (trials.parse::<u64>(), held_out.parse::<u64>(), seed.parse::<u64>())
    else {
        eprintln!("TRAIN_TRIALS, HELD_OUT_TRIALS and SEED must be whole numbers");
        return ExitCode::from(2);
    };
    match run(controller, trials, held_out, seed, std::path::Path::new(out)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{e}");
            ExitCode::FAILURE
        }
    }
}

fn run(controller: &str, trials: u64, held_out: u64, seed: u64, out: &std::path::Path) -> Result<(), String> {
    let data = shared_data().ok_or("the shared data corpus is missing (set KG_SHARED_DATA)")?;
    let bvh = data.join("bvh/cmu/02_01.bvh");
    let (clip, _) = read_bvh_file(&bvh, BvhReadOptions::default()).map_err(|e| e.to_string())?.value;
    let params = SimParams::default();
    let start = std::time::Instant::now();
    let set =
        sample_trials(clip.skeleton(), controller, None, (seed, 0, trials), &params).map_err(|e| e.to_string())?;
    let model = Arc::new(train(controller, seed, &set).map_err(|e| e.to_string())?);
    println!(
        "{controller}: {} training trials ({} successes) in {:.1} s; kernel ε {}, C {}; training accuracy {:.3} \
         (hand-written {:.3})",
        set.len(),
        model.provenance.successes,
        start.elapsed().as_secs_f64(),
        model.kernel_eps,
        model.c,
        model.provenance.training_accuracy,
        model.provenance.hand_accuracy
    );
    let fresh = sample_trials(clip.skeleton(), controller, Some(&model), (seed, trials, held_out), &params)
        .map_err(|e| e.to_string())?;
    let acc = model.accuracy(fresh.iter());
    println!(
        "{controller}: {} held-out trials ({} successes): learned {:.3}, hand-written {:.3}",
        acc.trials,
        fresh.iter().filter(|d| d.success).count(),
        acc.learned,
        acc.hand
    );
    let text = model.to_ron().map_err(|e| e.to_string())?;
    write_atomic(out, text.as_bytes()).map_err(|e| e.to_string())?;
    println!("wrote {}", out.display());
    Ok(())
}

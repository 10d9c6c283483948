//! `kg`: run, check, test and batch kinegraph graphs from the command line.

fn main() -> std::process::ExitCode {
    kinegraph::cli::main()
}

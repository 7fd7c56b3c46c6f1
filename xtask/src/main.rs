//! xtask: ossify's runner and developer commands.
//!
//! `cargo xtask <command>` (an alias in `.cargo/config.toml`, release mode). The runner
//! reads captures and artifacts, calls the stage crates in-process as libraries (never by
//! shelling out), keeps their artifacts in a content-addressed cache ([`cache`]) and
//! writes the output files. It is the only crate besides mocap-io and export that does
//! I/O, and the only one that prints.
#![allow(clippy::print_stdout)]
// The clap structs' doc comments are the commands' --help text, where `<name>` and
// `<project root>` are placeholders a reader of a terminal expects, not HTML.
#![allow(rustdoc::invalid_html_tags)]

mod bench;
mod cache;
mod eval;
mod inspect;
mod params_cmd;
mod pipeline;
mod progress;
mod run;
mod set_param;
mod stage_cmd;
mod synth_cmd;
mod tempdir;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// ossify's runner: capture in, skeleton out, with cached stages.
#[derive(Parser)]
#[command(name = "cargo xtask", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print a summary of a capture (C3D/TRC/CSV) or of an artifact (.cbor).
    Inspect(inspect::Args),
    /// Write a synthetic trial with ground truth (C3D, truth JSON, optional TRC).
    Synth(synth_cmd::Args),
    /// Run the whole pipeline on a capture, with cached stages, and write the outputs.
    Run(run::Args),
    /// Run one stage alone on artifact files (for Make, Snakemake, Nextflow).
    Stage(stage_cmd::Args),
    /// List every stage parameter with its default and meaning.
    Params(params_cmd::Args),
    /// Run the pipeline over a fixed synthetic suite and score it against the truth.
    Eval(eval::Args),
    /// Time reading a capture, each stage and the whole pipeline on a synthetic human.
    Bench(bench::Args),
    /// Manage the artifact cache.
    #[command(subcommand)]
    Cache(cache::Command),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Inspect(args) => inspect::main(&args),
        Command::Synth(args) => synth_cmd::main(&args),
        Command::Run(args) => run::main(&args),
        Command::Stage(args) => stage_cmd::main(&args),
        Command::Params(args) => params_cmd::main(&args),
        Command::Eval(args) => eval::main(&args),
        Command::Bench(args) => bench::main(&args),
        Command::Cache(command) => cache::main(&command),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error}");
            for cause in error.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::FAILURE
        }
    }
}

/// The workspace root (the folder holding `Cargo.toml`, `crates/` and `fixtures/`).
pub fn project_root() -> PathBuf {
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    manifest.parent().map(PathBuf::from).unwrap_or(manifest)
}

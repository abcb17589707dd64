//! Command-line interface: `cohortforge` serves the API; subcommands run offline tasks
//! (phantoms, fitting and evaluating models on directories of meshes, benchmarks).

pub mod bench;
mod bench_clusters;
pub mod bench_conditional;
mod bench_fidelity;
pub mod bench_models;
pub mod bench_privacy;
pub mod bench_report;
pub mod laterality_file;
pub mod memory;
pub mod mesh_dir;
pub mod model_file;
pub mod progress;
pub mod study;
pub mod tables;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand};
use tokio_util::sync::CancellationToken;

use crate::config::{Config, WorkerConfig};
use crate::mesh::{Format, io, phantom};
use crate::store::{Location, Store};

/// Generative models of anatomical shape, served as virtual cohorts.
#[derive(Parser, Debug)]
#[command(name = "cohortforge", version, args_conflicts_with_subcommands = true)]
pub struct Cli {
    /// Server settings (used when no subcommand is given).
    #[command(flatten)]
    pub serve: Config,
    /// Offline task to run instead of serving.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// Offline tasks.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Serve the HTTP API and run jobs (the default; `--workers 0` for an API-only replica).
    Serve(Config),
    /// Run jobs only, on the database of the API processes, with probes and `/metrics` on
    /// their own listener.
    Worker(WorkerConfig),
    /// Write synthetic phantom meshes with known ground truth, plus params.csv.
    Phantoms(PhantomArgs),
    /// Print the OpenAPI document as JSON.
    Openapi,
    /// Fit a shape model to a directory of meshes and write a model file.
    Fit(study::FitArgs),
    /// Evaluate a model file on test meshes: generalisation, matching, specificity,
    /// cohort acceptance, timings.
    Evaluate(study::EvaluateArgs),
    /// Fit models on phantoms with known ground truth and print benchmark tables.
    Bench(bench::BenchArgs),
}

/// Arguments of `cohortforge phantoms`.
#[derive(clap::Args, Debug)]
pub struct PhantomArgs {
    /// Shape family: `lv` (left-ventricle myocardium), `liver`, or `mixed` (genus-0
    /// ellipsoids and genus-1 tori, labelled `subpopulation` in params.csv).
    #[arg(long)]
    pub family: phantom::Family,
    /// Number of subjects.
    #[arg(long, default_value_t = 20)]
    pub count: usize,
    /// Random seed; the same seed writes the same files.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Output directory (created when missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Mesh file format: obj, stl, ply or vtk.
    #[arg(long, default_value = "obj", value_parser = parse_format)]
    pub format: Format,
}

fn parse_format(s: &str) -> Result<Format, String> {
    Format::from_name(s).ok_or_else(|| format!("unknown format '{s}': use obj, stl, ply or vtk"))
}

/// Outcome of a CLI command; an error is one line of text for the user.
pub type CliResult = Result<(), String>;

/// Runs the command line.
pub fn run(cli: Cli) -> CliResult {
    match cli.command {
        None => serve(cli.serve),
        Some(Command::Serve(config)) => serve(config),
        Some(Command::Worker(config)) => worker(config),
        Some(Command::Phantoms(args)) => write_phantoms(&args),
        Some(Command::Fit(args)) => study::fit(&args),
        Some(Command::Evaluate(args)) => study::evaluate_model(&args),
        Some(Command::Bench(args)) => bench::run(&args),
        Some(Command::Openapi) => {
            let json = crate::api::openapi()
                .to_pretty_json()
                .map_err(|e| e.to_string())?;
            println!("{json}");
            Ok(())
        }
    }
}

fn serve(config: Config) -> CliResult {
    let config = config.without_empty_tokens();
    config.validate().map_err(|e| e.to_string())?;
    let database = config.database.clone();
    let bind = config.bind;
    run_process(
        &database,
        bind,
        "cohortforge listening",
        |listener, store, stop| async move { crate::api::run(listener, &config, store, stop).await },
    )
}

fn worker(config: WorkerConfig) -> CliResult {
    config.validate().map_err(|e| e.to_string())?;
    let database = config.database.clone();
    let bind = config.bind;
    let started = "cohortforge worker running; probes and metrics listening";
    run_process(
        &database,
        bind,
        started,
        |listener, store, stop| async move {
            crate::api::run_workers(listener, &config, store, stop).await
        },
    )
}

/// Opens the database, binds `bind` and runs `service` until SIGINT or SIGTERM, then
/// closes the database.
fn run_process<F, Fut>(
    database: &Location,
    bind: SocketAddr,
    started: &str,
    service: F,
) -> CliResult
where
    F: FnOnce(tokio::net::TcpListener, Store, CancellationToken) -> Fut,
    Fut: std::future::Future<Output = std::io::Result<()>>,
{
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .map_err(|e| e.to_string())?;
    runtime.block_on(async move {
        let store = Store::connect(database)
            .await
            .map_err(|e| format!("cannot open database {database}: {e}"))?;
        let listener = tokio::net::TcpListener::bind(bind)
            .await
            .map_err(|e| format!("cannot listen on {bind}: {e}"))?;
        tracing::info!(bind = %bind, database = %database, "{started}");
        let shutdown = CancellationToken::new();
        tokio::spawn(stop_on_signal(shutdown.clone()));
        service(listener, store.clone(), shutdown)
            .await
            .map_err(|e| e.to_string())?;
        store.close().await;
        Ok(())
    })
}

/// Cancels `shutdown` on SIGINT (Ctrl-C) or SIGTERM (what container runtimes send).
async fn stop_on_signal(shutdown: CancellationToken) {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    let _ = tokio::signal::ctrl_c().await;
    tracing::info!("shutting down");
    shutdown.cancel();
}

fn write_phantoms(args: &PhantomArgs) -> CliResult {
    let phantoms = phantom::generate(args.family, args.count, args.seed);
    std::fs::create_dir_all(&args.out).map_err(|e| io_error(&args.out, e))?;
    for p in &phantoms {
        let path = args
            .out
            .join(format!("{}.{}", p.name, args.format.extension()));
        std::fs::write(&path, io::write(&p.mesh, args.format)).map_err(|e| io_error(&path, e))?;
    }
    let csv = args.out.join("params.csv");
    std::fs::write(&csv, phantom::params_csv(&phantoms)).map_err(|e| io_error(&csv, e))?;
    println!(
        "wrote {} {} phantoms and params.csv to {}",
        phantoms.len(),
        args.family,
        args.out.display()
    );
    Ok(())
}

fn io_error(path: &Path, e: std::io::Error) -> String {
    format!("{}: {e}", path.display())
}

/// Writes `value` as pretty JSON to `path`.
fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> CliResult {
    let json = serde_json::to_vec_pretty(value).map_err(|e| e.to_string())?;
    std::fs::write(path, json).map_err(|e| io_error(path, e))
}

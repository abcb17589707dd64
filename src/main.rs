use clap::Parser;
use tracing_subscriber::EnvFilter;

fn main() {
    tracing_subscriber::fmt()
        .with_env_filter(
            EnvFilter::try_from_env("COHORTFORGE_LOG")
                .unwrap_or_else(|_| EnvFilter::new("info,sqlx=warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = cohortforge::cli::Cli::parse();
    if let Err(message) = cohortforge::cli::run(cli) {
        eprintln!("error: {message}");
        std::process::exit(1);
    }
}

//! The `voxd` command line: voxelize meshes, inspect and convert volumes, combine them, run the
//! service, benchmark engines. This file only dispatches; `cli/` translates arguments into the
//! library's application requests and results into output.

mod cli;

use std::process::ExitCode;

use clap::Parser;
use cli::args::{Cli, Command};
use cli::commands;

/// Large blocks on transparent huge pages, kept for reuse when freed (`voxd::alloc`;
/// `VOXD_HUGE_PAGES`, `VOXD_LARGE_CACHE_MIB`).
#[global_allocator]
static ALLOC: voxd::alloc::HugePages = voxd::alloc::HugePages;

fn main() -> ExitCode {
    if let Err(e) = voxd::alloc::configure() {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        // Mesa prints "XDG_RUNTIME_DIR is invalid" on every start without it; nothing is
        // written there by a compute-only device.
        // SAFETY: single-threaded at this point, before any thread or engine is started.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    let cli = Cli::parse();
    init_logging(&cli);
    let result = match cli.command {
        Command::Voxelize(a) => commands::voxelize(&a),
        Command::Info { file } => commands::info(&file),
        Command::Convert { input, output } => commands::convert(&input, &output),
        Command::Serve(a) => serve(&a),
        Command::Normals { input, output } => commands::normals(&input, &output),
        Command::Morph {
            op,
            input,
            output,
            radius,
            kernel,
            grow,
        } => commands::morph(op, &input, &output, radius, kernel, grow),
        Command::Csg { op, inputs, output } => match cli::distance::is_distance(&inputs[0]) {
            Ok(true) => cli::distance::csg(op, &inputs, &output),
            Ok(false) => commands::csg(op, &inputs, &output),
            Err(e) => Err(e),
        },
        Command::Threshold {
            input,
            level,
            output,
        } => cli::distance::threshold(&input, level, &output),
        Command::Mesh(a) => cli::mesh::mesh(&a),
        Command::Hermite(a) => cli::mesh::hermite(&a),
        Command::Sdf {
            input,
            band,
            output,
        } => cli::distance::sdf(&input, band, &output),
        Command::Bench(a) => cli::bench::run(&a),
        Command::Keygen { name } => voxd::service::auth::generate(&name).map(|(key, line)| {
            println!("{key}\n{line}");
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("voxd: error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Log lines on stderr, as `--log-format` says. `VOXD_LOG` (an env filter) chooses which; by
/// default `serve` logs info and above from voxd (its start, the access log at target
/// `voxd::access`, one line per request, and its jobs' lines), other commands warnings only.
fn init_logging(cli: &Cli) {
    let default = match cli.command {
        Command::Serve(_) => "warn,voxd=info",
        _ => "warn",
    };
    let filter =
        tracing_subscriber::EnvFilter::try_from_env("VOXD_LOG").unwrap_or_else(|_| default.into());
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    match cli.log_format {
        // One JSON object per line: the event's fields at the top level (`flatten_event`), the
        // span it is in (`span`: a request's or a job's ids) and the spans around it.
        cli::args::LogFormat::Json => builder
            .json()
            .flatten_event(true)
            .with_current_span(true)
            .with_span_list(true)
            .init(),
        // Colours only on a terminal: logs to a file, a pipe or a container runtime stay plain.
        cli::args::LogFormat::Text => builder
            .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
            .init(),
    }
}

fn serve(a: &cli::args::ServeArgs) -> Result<(), String> {
    let rt = tokio::runtime::Runtime::new().map_err(|e| e.to_string())?;
    let served = rt.block_on(voxd::service::serve(
        a.config(),
        shutdown_signal(),
        |addr, admin| {
            // The service's line first (scripts and tests read the first line), then the
            // admin listener's. A closed stdout (a reader that took its line and left) is not
            // an error.
            use std::io::Write;
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "voxd listening on http://{addr}");
            if let Some(a) = admin {
                let _ = writeln!(out, "voxd admin listening on http://{a}");
            }
            let _ = out.flush();
        },
    ));
    // Work still running after the shutdown timeout is left behind, not waited for.
    rt.shutdown_timeout(std::time::Duration::from_secs(1));
    served
}

/// SIGTERM or Ctrl-C.
async fn shutdown_signal() {
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending().await,
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => {},
        _ = term => {},
    }
    tracing::info!("shutdown signal received");
}

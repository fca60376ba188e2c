//! `ves`: the VES command line. Parses, runs one subcommand ([`commands`]), prints an error with its
//! cause chain on one line, and maps it to the exit status: 0 done, 1 error, 2 verification
//! outside its tolerances.

mod commands;
mod terminal;
mod workshop;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    use tracing_subscriber::Layer as _;
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::util::SubscriberInitExt;
    // Without a terminal (a batch job, a CI log), the stages of a long run are log lines
    // (terminal::PROGRESS_TARGET); VES_LOG replaces this default.
    let filter = tracing_subscriber::EnvFilter::try_from_env("VES_LOG").unwrap_or_else(|_| {
        if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
            "warn".into()
        } else {
            format!("warn,{}=info", terminal::PROGRESS_TARGET).into()
        }
    });
    tracing_subscriber::registry()
        .with(
            tracing_subscriber::fmt::layer()
                // On stderr, with the progress bars lifted while a line is written.
                .with_writer(terminal::LogWriter)
                // Colour codes only for a terminal, not in logs and pipes.
                .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
                .with_filter(filter),
        )
        // Warnings also go to `--json` (whatever VES_LOG shows).
        .with(terminal::Notices)
        .init();
    // A panic is a bug, but the user still gets one line (set VES_LOG=debug for the default
    // report with its location).
    if std::env::var_os("VES_LOG").is_none() {
        std::panic::set_hook(Box::new(|info| {
            let msg = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_default();
            eprintln!("internal error (please report): {}", msg.replace('\n', " "));
        }));
    }
    let done = commands::run(commands::Cli::parse());
    // Threads still running (a viewer's compute) may hold work folders: they go now.
    ves_pipeline::workdir::remove_all();
    match done {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if commands::rank() == 0 {
                eprintln!("error: {e:#}");
            }
            ExitCode::from(if e.is::<commands::VerifyFailed>() { 2 } else { 1 })
        }
    }
}

//! `modalforge`: see `modalforge --help` and the README.

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    // A bug must still end in one line, not a backtrace.
    std::panic::set_hook(Box::new(|info| {
        eprintln!("error: internal error (please report): {info}");
    }));
    // The solvers are written for one core (the plugin solves on one worker thread); faer's
    // dense helpers would otherwise spin a thread pool for small products.
    faer::set_global_parallelism(faer::Par::Seq);
    let cli = match cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => e.exit(), // --help, --version
        Err(e) => {
            eprintln!("{}", one_line(&e));
            return ExitCode::from(2);
        }
    };
    match cli::run(cli) {
        Ok(text) => {
            use std::io::Write;
            let mut out = std::io::stdout().lock();
            match writeln!(out, "{text}").and_then(|()| out.flush()) {
                Ok(()) => ExitCode::SUCCESS,
                // The reader went away (`modalforge ... | head`): nobody is left to tell, and
                // it is not a bug (`println!` panicked here: "internal error").
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("error: cannot write the output: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// clap's own errors span several lines: keep the first, with the allowed values when clap
/// lists them, and point at --help.
fn one_line(e: &clap::Error) -> String {
    use clap::error::{ContextKind, ContextValue};
    let text = e.to_string();
    let first = text.lines().next().unwrap_or("invalid arguments");
    match (
        e.get(ContextKind::ValidValue),
        e.get(ContextKind::InvalidArg),
    ) {
        (Some(ContextValue::Strings(values)), _) if !values.is_empty() => {
            format!("{first}: use {} (see modalforge --help)", values.join(", "))
        }
        // "the following required arguments were not provided:" lists them on the next lines.
        (_, Some(ContextValue::Strings(args))) if first.ends_with(':') => {
            format!("{first} {} (see modalforge --help)", args.join(", "))
        }
        _ => format!("{first} (see modalforge --help)"),
    }
}

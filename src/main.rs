//! The `prism` command: parses arguments and calls the library.

mod args;
mod cli;
mod farm;
mod serve;
mod tev;

fn main() -> std::process::ExitCode {
    cli::run()
}

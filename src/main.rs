//! The `prism` command: parses arguments and calls the library.

mod cli;
mod farm;
mod serve;

fn main() -> std::process::ExitCode {
    cli::run()
}

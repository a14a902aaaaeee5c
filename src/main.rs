//! The `prism` command: parses arguments and calls the library.

mod cli;
mod farm;

fn main() -> std::process::ExitCode {
    cli::run()
}

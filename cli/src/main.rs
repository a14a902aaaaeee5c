//! The `prism` command: parses arguments and calls the library.

mod args;
mod commands;
mod farm;
mod serve;
mod tev;

fn main() -> std::process::ExitCode {
    commands::run()
}

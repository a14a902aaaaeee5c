//! The `prism` command: parses arguments and calls the library.

/// `eprintln!` of one line whose pieces may come from files or arguments
/// (names, paths, library messages): control characters escaped by
/// `prism::text::escape_controls`, so none drives the terminal or forges a
/// line. Every one-line message of the command goes through it.
macro_rules! say_err {
    ($($arg:tt)*) => {
        eprintln!("{}", prism::text::escape_controls(&format!($($arg)*)))
    };
}

mod args;
mod commands;
mod farm;
mod serve;
mod tev;

fn main() -> std::process::ExitCode {
    commands::run()
}

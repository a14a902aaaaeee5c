//! `prism merge`: EXR parts of one frame (from `--crop` or `--tile`) into
//! the whole image, byte-identical to the image rendered in one process.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use prism::image_io::merge_parts;

use super::BAD_INPUT;

#[derive(Args)]
pub struct MergeArgs {
    /// The EXR parts, in any order.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// The merged image; the format follows the extension.
    #[arg(short, long)]
    output: PathBuf,
}

pub fn merge_command(args: &MergeArgs) -> ExitCode {
    match merge_parts(&args.parts, &args.output) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            say_err!("error: {e}");
            ExitCode::from(BAD_INPUT)
        }
    }
}

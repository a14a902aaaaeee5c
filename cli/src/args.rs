//! What every subcommand shares: exit codes, the scene's read options,
//! the frame-range syntax. Below cli/, farm/ and serve/, which all use it
//! and none of which imports another's internals.

use std::path::PathBuf;

use clap::Args;
use prism::limits;
use prism::scene::LoadOptions;

/// Exit code for bad input: arguments, scene file, output path.
pub const BAD_INPUT: u8 = 2;
/// 128 + SIGINT, what shells report for a program stopped by Ctrl-C.
pub const INTERRUPTED: u8 = 130;

/// What a scene may read and use while loading.
#[derive(Args)]
pub struct LoadArgs {
    /// Let the scene read files below DIR too (repeatable). By default a
    /// scene reads only below its own folder; PRISM_ALLOW_READ adds folders
    /// separated by ':'.
    #[arg(long, value_name = "DIR")]
    allow_read: Vec<PathBuf>,
    /// Memory for decoded textures, in MiB.
    #[arg(long, value_name = "MIB", default_value_t = limits::DEFAULT_TEXTURE_MIB,
          value_parser = clap::value_parser!(u64).range(1..=1 << 30))]
    texture_memory: u64,
    /// Look through the model camera of this name (a glTF camera's node
    /// or own name) instead of the scene's camera.
    #[arg(long, value_name = "NAME")]
    camera: Option<String>,
}

impl Default for LoadArgs {
    /// What a scene reads with no options: its own folder and
    /// PRISM_ALLOW_READ's.
    fn default() -> Self {
        LoadArgs {
            allow_read: Vec::new(),
            texture_memory: limits::DEFAULT_TEXTURE_MIB,
            camera: None,
        }
    }
}

impl LoadArgs {
    /// The load options, or a message naming a folder that does not exist.
    pub fn options(&self) -> Result<LoadOptions, String> {
        Ok(LoadOptions {
            camera: self.camera.clone(),
            ..LoadOptions::with_allow_read(&self.allow_read, self.texture_memory)?
        })
    }
}

/// `A-B` with A <= B, or a single frame `A`.
pub fn parse_frames(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected a frame range A-B (e.g. 0-47), got `{s}`");
    let (a, b) = s.split_once('-').unwrap_or((s, s));
    let (a, b) = (
        a.trim().parse::<u32>().map_err(|_| bad())?,
        b.trim().parse::<u32>().map_err(|_| bad())?,
    );
    if a > b {
        return Err(format!("frame range {a}-{b} is reversed"));
    }
    Ok((a, b))
}

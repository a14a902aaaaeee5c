//! `prism farm merge`: the merge step of a farm render. Each frame whose
//! parts are all there is merged on its own, so one bad frame does not
//! hold back the others. A refusal is written to `failed/frame_####.txt`
//! (shown by `prism farm status`), and the part to blame is moved to
//! `parts/refused/`: the part is then missing, and the next
//! `prism farm slurm` renders it again instead of resubmitting a merge
//! that must fail.

use std::path::{Path, PathBuf};

use prism::image_io::{Part, merge_parts_with};
use prism::render::Region;

use super::{Failure, Plan, Progress, write_file};

pub fn run(outdir: &Path, only: Option<u32>) -> Result<(), Failure> {
    let plan = Plan::read(outdir)?;
    if let Some(f) = only
        && !plan.frames().contains(&f)
    {
        return Err(Failure::BadInput(format!(
            "frame {f} is not in this farm render (frames {}-{})",
            plan.first_frame, plan.last_frame
        )));
    }
    let progress = Progress::of(&plan, outdir);
    let mut failed = Vec::new();
    for frame in progress.mergeable {
        if only.is_some_and(|f| f != frame) {
            continue;
        }
        match merge_frame(&plan, outdir, frame) {
            Ok(out) => say!("prism farm: merged frame {frame} -> {}", out.display()),
            Err(why) => {
                say_err!("prism farm: frame {frame} not merged: {why}");
                failed.push(frame);
            }
        }
    }
    if failed.is_empty() {
        Ok(())
    } else {
        let list: Vec<String> = failed.iter().map(u32::to_string).collect();
        Err(Failure::Failed(format!(
            "frames {} were not merged; `prism farm status {}` says why, and \
             `prism farm slurm` again renders the refused parts",
            list.join(", "),
            outdir.display()
        )))
    }
}

/// Merges `frame`'s parts; on a refusal records why and sets the part to
/// blame aside.
fn merge_frame(plan: &Plan, outdir: &Path, frame: u32) -> Result<PathBuf, String> {
    let paths: Vec<PathBuf> = (0..plan.tiles)
        .map(|t| outdir.join(Plan::part(frame, t)))
        .collect();
    let output = outdir.join(plan.frame_file(frame));
    let failure = outdir.join(Plan::failure_file(frame));
    // Each part must be its own tile of this frame, not another's copied
    // under its name.
    let expected = |path: &Path, part: &Part| -> Result<(), String> {
        let tile = paths.iter().position(|p| p == path).unwrap_or_default() as u32;
        let (w, h) = (part.film.width(), part.film.height());
        let region = Region::tile(tile, plan.tiles, w, h)?;
        if part.provenance.frame != frame {
            return Err(format!(
                "is a part of frame {}, not of frame {frame}",
                part.provenance.frame
            ));
        }
        if part.film.region() != region {
            return Err(format!(
                "holds region {}, not tile {tile}'s region {region}",
                part.film.region()
            ));
        }
        Ok(())
    };
    match merge_parts_with(&paths, &output, expected) {
        Ok(()) => {
            let _ = std::fs::remove_file(&failure);
            Ok(output)
        }
        Err(e) => {
            let mut why = e.message.clone();
            if let Some(part) = &e.part
                && let Some(name) = part.file_name()
            {
                let refused = outdir.join("parts/refused");
                let moved = std::fs::create_dir_all(&refused)
                    .and_then(|()| std::fs::rename(part, refused.join(name)));
                match moved {
                    Ok(()) => {
                        why.push_str(" (set aside in parts/refused/; a rerun renders it again)")
                    }
                    Err(err) => why.push_str(&format!(" (could not be set aside: {err})")),
                }
            }
            let recorded = std::fs::create_dir_all(outdir.join("failed"))
                .map_err(|e| Failure::Failed(e.to_string()))
                .and_then(|()| write_file(&failure, &format!("{why}\n")));
            if let Err(Failure::Failed(e) | Failure::BadInput(e)) = recorded {
                why.push_str(&format!(" (the reason could not be recorded: {e})"));
            }
            Err(why)
        }
    }
}

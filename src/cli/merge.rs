//! `prism merge`: EXR parts of one frame (from `--crop` or `--tile`) into
//! the whole image, byte-identical to the image rendered in one process.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

use clap::Args;
use prism::image_io::{Part, check_writable, read_part, write_film_unless};
use prism::render::{Film, Region};

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
    match merge(&args.parts, &args.output) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(BAD_INPUT)
        }
    }
}

fn merge(paths: &[PathBuf], output: &Path) -> Result<(), String> {
    check_writable(output).map_err(|e| e.to_string())?;
    let mut parts: Vec<(PathBuf, Part)> = Vec::with_capacity(paths.len());
    for (i, path) in paths.iter().enumerate() {
        if paths[..i].contains(path) {
            return Err(format!("{}: is given twice", path.display()));
        }
        let part = read_part(path).map_err(|e| format!("{}: {e}", path.display()))?;
        if let Some((first_path, first)) = parts.first() {
            if let Some((field, ours, theirs)) = first.provenance.difference(&part.provenance) {
                return Err(format!(
                    "{}: belongs to another render: its {field} is `{theirs}`, \
                     but {} has `{ours}`",
                    path.display(),
                    first_path.display()
                ));
            }
            let (a, b) = (&first.film, &part.film);
            if (a.width(), a.height()) != (b.width(), b.height()) {
                return Err(format!(
                    "{}: is a part of a {}x{} image, {} of a {}x{} one",
                    path.display(),
                    b.width(),
                    b.height(),
                    first_path.display(),
                    a.width(),
                    a.height()
                ));
            }
        }
        if let Some((other, _)) = parts
            .iter()
            .find(|(_, p)| p.film.region().overlaps(&part.film.region()))
        {
            return Err(format!(
                "{}: its region {} overlaps {}'s region {}",
                path.display(),
                part.film.region(),
                other.display(),
                parts
                    .iter()
                    .find(|(p, _)| p == other)
                    .map_or(String::new(), |(_, p)| p.film.region().to_string())
            ));
        }
        parts.push((path.clone(), part));
    }
    let first = &parts[0].1;
    let (width, height) = (first.film.width(), first.film.height());
    let regions: Vec<Region> = parts.iter().map(|(_, p)| p.film.region()).collect();
    let missing = missing_regions(width, height, &regions);
    if !missing.is_empty() {
        let list: Vec<String> = missing.iter().map(Region::to_string).collect();
        return Err(format!(
            "the parts do not cover the {width}x{height} image; missing regions (X0,X1,Y0,Y1): {}",
            list.join(" ")
        ));
    }
    let mut film = Film::new(width, height);
    for (_, part) in &parts {
        film.paste(part.film.region(), part.film.pixels());
    }
    write_film_unless(
        &film,
        output,
        Some(&first.provenance),
        &AtomicBool::new(false),
    )
    .map_err(|e| e.to_string())
}

/// The pixels of the frame no region covers (the regions do not overlap),
/// as rectangles: runs of rows with the same uncovered column spans.
pub fn missing_regions(width: u32, height: u32, regions: &[Region]) -> Vec<Region> {
    let spans_of_row = |y: u32| {
        let mut covered: Vec<(u32, u32)> = regions
            .iter()
            .filter(|r| r.y0 <= y && y < r.y1)
            .map(|r| (r.x0, r.x1))
            .collect();
        covered.sort_unstable();
        let mut gaps = Vec::new();
        let mut x = 0;
        for (x0, x1) in covered {
            if x0 > x {
                gaps.push((x, x0));
            }
            x = x.max(x1);
        }
        if x < width {
            gaps.push((x, width));
        }
        gaps
    };
    let mut missing: Vec<Region> = Vec::new();
    let mut open: Vec<Region> = Vec::new();
    for y in 0..=height {
        let gaps = if y < height {
            spans_of_row(y)
        } else {
            Vec::new()
        };
        // Rectangles whose span continues grow by a row; the others close.
        let mut still = Vec::new();
        for r in open.drain(..) {
            if gaps.contains(&(r.x0, r.x1)) {
                still.push(Region { y1: y + 1, ..r });
            } else {
                missing.push(r);
            }
        }
        for (x0, x1) in gaps {
            if !still.iter().any(|r| (r.x0, r.x1) == (x0, x1)) {
                still.push(Region {
                    x0,
                    x1,
                    y0: y,
                    y1: y + 1,
                });
            }
        }
        open = still;
    }
    missing.sort();
    missing
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_regions_are_the_uncovered_rectangles() {
        let tiles: Vec<Region> = (0..4).map(|i| Region::tile(i, 4, 8, 10).unwrap()).collect();
        assert!(missing_regions(8, 10, &tiles).is_empty());
        assert_eq!(
            missing_regions(8, 10, &[tiles[0], tiles[2]]),
            vec![tiles[1], tiles[3]]
        );
        // A hole in the middle of a band.
        let left = Region {
            x0: 0,
            x1: 3,
            y0: 0,
            y1: 4,
        };
        let right = Region {
            x0: 5,
            x1: 8,
            y0: 0,
            y1: 4,
        };
        assert_eq!(
            missing_regions(8, 4, &[left, right]),
            vec![Region {
                x0: 3,
                x1: 5,
                y0: 0,
                y1: 4
            }]
        );
        assert_eq!(missing_regions(2, 2, &[]), vec![Region::full(2, 2)]);
    }
}

//! Merging EXR parts of one frame (from `--crop`, `--tile` or a farm)
//! into the whole image, byte-identical to the image rendered in one
//! process. Every part is checked (its digest, its pixels, that it belongs
//! to the same render as the others) and a refusal names the part to blame,
//! so a farm can set it aside and render it again.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use super::{Part, check_writable, read_part, write_film_unless};
use crate::render::{Film, Region};

/// Why parts could not be merged.
#[derive(Debug)]
pub struct MergeError {
    /// The part to blame, where one is: unreadable, damaged, of another
    /// render, or overlapping another.
    pub part: Option<PathBuf>,
    /// What is wrong, naming the files.
    pub message: String,
}

impl std::fmt::Display for MergeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for MergeError {}

fn blame(part: &Path, message: String) -> MergeError {
    MergeError {
        part: Some(part.to_path_buf()),
        message: format!("{}: {message}", part.display()),
    }
}

fn refuse(message: String) -> MergeError {
    MergeError {
        part: None,
        message,
    }
}

/// Merges the EXR parts at `paths` (any order) into `output`, written
/// atomically in the format its extension names. The output may not be one
/// of the parts.
pub fn merge_parts(paths: &[PathBuf], output: &Path) -> Result<(), MergeError> {
    merge_parts_with(paths, output, |_, _| Ok(()))
}

/// [`merge_parts`], each part read also passing `expected` (a farm knows
/// which tile each file must hold); its refusal blames the part.
pub fn merge_parts_with(
    paths: &[PathBuf],
    output: &Path,
    expected: impl Fn(&Path, &Part) -> Result<(), String>,
) -> Result<(), MergeError> {
    check_writable(output).map_err(|e| refuse(e.to_string()))?;
    if let Ok(out) = output.canonicalize()
        && let Some(same) = paths
            .iter()
            .find(|p| p.canonicalize().is_ok_and(|p| p == out))
    {
        return Err(refuse(format!(
            "{}: is one of the parts ({}); merging onto a part would destroy it",
            output.display(),
            same.display()
        )));
    }
    let mut parts: Vec<(PathBuf, Part)> = Vec::with_capacity(paths.len());
    for (i, path) in paths.iter().enumerate() {
        if paths[..i].contains(path) {
            return Err(blame(path, "is given twice".into()));
        }
        let part = read_part(path).map_err(|e| blame(path, e))?;
        expected(path, &part).map_err(|e| blame(path, e))?;
        parts.push((path.clone(), part));
    }
    let Some(reference) = most_common_provenance(&parts) else {
        return Err(refuse("no parts to merge".into()));
    };
    let (ref_path, first) = &parts[reference];
    for (path, part) in &parts {
        if let Some((field, ours, theirs)) = first.provenance.difference(&part.provenance) {
            return Err(blame(
                path,
                format!(
                    "belongs to another render: its {field} is `{theirs}`, but {} has `{ours}`",
                    ref_path.display()
                ),
            ));
        }
        let (a, b) = (&first.film, &part.film);
        if (a.width(), a.height()) != (b.width(), b.height()) {
            return Err(blame(
                path,
                format!(
                    "is a part of a {}x{} image, {} of a {}x{} one",
                    b.width(),
                    b.height(),
                    ref_path.display(),
                    a.width(),
                    a.height()
                ),
            ));
        }
    }
    for (i, (path, part)) in parts.iter().enumerate() {
        let region = part.film.region();
        if let Some((other, theirs)) = parts[..i]
            .iter()
            .find(|(_, p)| p.film.region().overlaps(&region))
        {
            return Err(blame(
                path,
                format!(
                    "its region {region} overlaps {}'s region {}",
                    other.display(),
                    theirs.film.region()
                ),
            ));
        }
    }
    let (width, height) = (first.film.width(), first.film.height());
    let regions: Vec<Region> = parts.iter().map(|(_, p)| p.film.region()).collect();
    let missing = missing_regions(width, height, &regions);
    if !missing.is_empty() {
        let list: Vec<String> = missing.iter().map(Region::to_string).collect();
        return Err(refuse(format!(
            "the parts do not cover the {width}x{height} image; missing regions (X0,X1,Y0,Y1): {}",
            list.join(" ")
        )));
    }
    let mut film = Film::new(width, height);
    for (_, part) in &parts {
        film.paste(part.film.region(), part.film.pixels());
    }
    // The parts' exposure, for the 8-bit encodings, as `prism render`
    // applies it.
    if matches!(
        super::OutputFormat::from_path(output),
        Ok(super::OutputFormat::Png | super::OutputFormat::Ppm)
    ) {
        let ev = crate::RenderSettings::exposure_in_key(&first.provenance.settings);
        super::expose(&mut film, ev);
    }
    write_film_unless(
        &film,
        output,
        Some(&first.provenance),
        &AtomicBool::new(false),
    )
    .map_err(|e| refuse(e.to_string()))
}

/// The index of a part whose provenance most parts share (the first such
/// on a tie): the odd one out is the one to blame.
fn most_common_provenance(parts: &[(PathBuf, Part)]) -> Option<usize> {
    let count = |i: usize| {
        parts
            .iter()
            .filter(|(_, p)| p.provenance == parts[i].1.provenance)
            .count()
    };
    (0..parts.len()).max_by_key(|&i| (count(i), std::cmp::Reverse(i)))
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

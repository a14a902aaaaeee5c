//! Slurm: the plan as two batch scripts, `render.sbatch` (a job array,
//! task k rendering part k % tiles of frame first + k / tiles) and
//! `merge.sbatch` (`prism farm merge`: every frame whose parts are all
//! there, each on its own), and their submission with `sbatch`, the merge
//! after the array (`--dependency=afterany`).
//!
//! No value from the user reaches a shell or Slurm unquoted: paths appear
//! only in the script bodies, in single quotes; the `#SBATCH` lines hold
//! only fixed text and checked numbers and names; the log paths are given
//! to `sbatch` as arguments (run without a shell), with every `%` of the
//! folder's name doubled, since Slurm expands its `%` patterns in the
//! whole path. A backslash, which turns those patterns off, is refused.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use super::{Failure, Paths, Plan, Progress, SlurmArgs, plan_in, shell_word, write_file};

/// Submitted job IDs, one `render ID` or `merge ID` line each.
const JOBS: &str = "jobs.txt";
const BACKEND: &str = "the Slurm backend";
/// Slurm's MaxArraySize when slurm.conf does not set it.
const DEFAULT_MAX_ARRAY_SIZE: u64 = 1001;

pub fn run(args: &SlurmArgs) -> Result<(), Failure> {
    if let Some(p) = &args.partition {
        check_partition(p)?;
    }
    check_log_folder(&args.common.output)?;
    let (plan, paths) = plan_in(&args.common, BACKEND)?;
    check_log_folder(&paths.outdir)?;
    let outdir = paths.outdir.clone();
    // Check first, act after: nothing is cancelled, written or submitted
    // unless all of it can be.
    let progress = Progress::of(&plan, &outdir);
    if args.submit {
        let running = active_jobs(&outdir, "render", "PENDING,RUNNING,SUSPENDED,REQUEUED");
        let merging = active_jobs(&outdir, "merge", "RUNNING");
        if !running.is_empty() || !merging.is_empty() {
            return Err(Failure::BadInput(format!(
                "jobs {} of this folder are still queued or running; wait for them \
                 (prism farm status {}) or cancel them with scancel",
                [running, merging].concat().join(", "),
                shell_word(paths.outdir())
            )));
        }
    }
    // The cluster is asked only when submitting: without a controller to
    // answer, scontrol waits for seconds.
    if let Some(&last) = progress.missing_tasks.last()
        && args.submit
        && let Some(max) = max_array_size()
        && last >= max
    {
        return Err(Failure::BadInput(format!(
            "task {last} is beyond this cluster's MaxArraySize ({max}: array indices up to {}); \
             use fewer frames or tiles per farm render",
            max - 1
        )));
    }
    write_file(
        &outdir.join("render.sbatch"),
        &render_script(&plan, &paths, args),
    )?;
    write_file(&outdir.join("merge.sbatch"), &merge_script(&paths, args))?;

    if progress.missing_tasks.is_empty() && progress.mergeable.is_empty() {
        say!(
            "{}: every frame is merged; nothing to submit",
            outdir.display()
        );
        return Ok(());
    }
    let array = array_spec(&progress.missing_tasks, args.max_running);
    let render_args = [
        format!("--array={array}"),
        log_option(&paths, "render_%A_%a.log"),
        script(&paths, "render.sbatch"),
    ];
    let merge_args = [
        log_option(&paths, "merge_%j.log"),
        script(&paths, "merge.sbatch"),
    ];
    if !args.submit {
        say!(
            "wrote {0}/render.sbatch and {0}/merge.sbatch; to submit:",
            outdir.display()
        );
        let words = |args: &[String]| {
            args.iter()
                .map(|a| shell_word(a))
                .collect::<Vec<_>>()
                .join(" ")
        };
        if progress.missing_tasks.is_empty() {
            say!("  sbatch {}", words(&merge_args));
        } else {
            say!("  id=$(sbatch --parsable {})", words(&render_args));
            say!("  sbatch --dependency=afterany:$id {}", words(&merge_args));
        }
        if progress.missing_tasks.last() >= Some(&DEFAULT_MAX_ARRAY_SIZE) {
            say!(
                "note: task indices reach {}; Slurm's default MaxArraySize ({DEFAULT_MAX_ARRAY_SIZE}) \
                 allows up to {} (scontrol show config | grep MaxArraySize)",
                progress.missing_tasks.last().unwrap_or(&0),
                DEFAULT_MAX_ARRAY_SIZE - 1
            );
        }
        return Ok(());
    }
    // A merge still waiting is replaced by the one submitted now.
    for id in active_jobs(&outdir, "merge", "PENDING") {
        let _ = Command::new("scancel").arg(&id).status();
    }
    let mut dependency = Vec::new();
    if !progress.missing_tasks.is_empty() {
        let id = sbatch(&outdir, &render_args)?;
        record(&outdir, "render", &id)?;
        say!(
            "submitted render job {id}: {} tasks ({array})",
            progress.missing_tasks.len()
        );
        // afterany: the merge runs whatever became of the tasks and merges
        // every frame that is whole.
        dependency.push(format!("--dependency=afterany:{id}"));
    }
    let id = sbatch(&outdir, &[dependency, merge_args.to_vec()].concat())?;
    record(&outdir, "merge", &id)?;
    say!("submitted merge job {id}");
    Ok(())
}

/// Slurm partition names: letters, digits, `_`, `.` and `-`, several
/// separated by commas. Anything else is refused rather than quoted: a
/// `#SBATCH` line is not a shell line.
fn check_partition(p: &str) -> Result<(), Failure> {
    let bad = p
        .chars()
        .find(|&c| !(c.is_ascii_alphanumeric() || "_.-,".contains(c)));
    match bad {
        _ if p.is_empty() => Err(Failure::BadInput(
            "--partition: expected a partition name".into(),
        )),
        Some(c) => Err(Failure::BadInput(format!(
            "--partition {p:?}: contains {c:?}, which {BACKEND} does not allow in a partition \
             name (letters, digits, `_`, `.`, `-`, and `,` between names)"
        ))),
        None => Ok(()),
    }
}

/// Slurm reads a backslash in a log path as "no patterns here", which
/// would turn the escaped `%%` of the folder's name back into two `%`.
fn check_log_folder(outdir: &Path) -> Result<(), Failure> {
    if outdir.to_string_lossy().contains('\\') {
        return Err(Failure::BadInput(format!(
            "the output folder {:?}: contains a backslash, which {BACKEND} cannot carry in \
             log paths; rename it",
            outdir.display().to_string()
        )));
    }
    Ok(())
}

/// `--output=` for a job's log in the output folder's logs/: `name`'s
/// patterns (`%A`, `%a`, `%j`) expanded, the folder's `%` kept.
fn log_option(paths: &Paths, name: &str) -> String {
    format!("--output={}/logs/{name}", paths.outdir().replace('%', "%%"))
}

fn script(paths: &Paths, name: &str) -> String {
    format!("{}/{name}", paths.outdir())
}

/// The `#SBATCH` lines: fixed names and checked values only. (The log
/// path is an argument of `sbatch`; see the module's comment.)
fn directives(args: &SlurmArgs, name: &str) -> String {
    let mut s = format!("#!/bin/bash\n#SBATCH --job-name={name}\n");
    if let Some(p) = &args.partition {
        let _ = writeln!(s, "#SBATCH --partition={p}");
    }
    if let Some(c) = args.cpus_per_task {
        let _ = writeln!(s, "#SBATCH --cpus-per-task={c}");
    }
    s
}

fn render_script(plan: &Plan, paths: &Paths, args: &SlurmArgs) -> String {
    let mut s = directives(args, "prism-render");
    let last = plan.task_count() - 1;
    let throttle = args.max_running.map_or(String::new(), |k| format!("%{k}"));
    let _ = write!(
        s,
        "#SBATCH --array=0-{last}{throttle}\n\
         # Written by `prism farm slurm`: task k renders tile k % TILES of frame\n\
         # FIRST + k / TILES into parts/ (written atomically: a part that exists\n\
         # is whole). Submit as `prism farm slurm` prints (it names the logs).\n\
         # Rerun `prism farm slurm` to submit only what is missing.\n\
         set -euo pipefail\n\
         PRISM={prism}\nSCENE={scene}\nOUT={out}\nTILES={tiles}\nFIRST={first}\n\
         k=${{SLURM_ARRAY_TASK_ID:?run this script as a Slurm array job}}\n\
         frame=$(( FIRST + k / TILES ))\n\
         tile=$(( k % TILES ))\n\
         part=$(printf '%s/parts/frame_%04d_tile_%04d.exr' \"$OUT\" \"$frame\" \"$tile\")\n\
         echo \"prism farm: task $k frame $frame tile $tile/$TILES on $(hostname)\"\n\
         exec \"$PRISM\" render \"$SCENE\" --frame \"$frame\" --tile \"$tile/$TILES\" -o \"$part\" \\\n\
         \x20   ${{SLURM_CPUS_PER_TASK:+--threads \"$SLURM_CPUS_PER_TASK\"}}\n",
        prism = shell_word(paths.prism()),
        scene = shell_word(paths.scene()),
        out = shell_word(paths.outdir()),
        tiles = plan.tiles,
        first = plan.first_frame,
    );
    s
}

fn merge_script(paths: &Paths, args: &SlurmArgs) -> String {
    let mut s = directives(args, "prism-merge");
    let _ = write!(
        s,
        "# Written by `prism farm slurm`: merges every frame whose parts are all\n\
         # there, each on its own; a part the merge refuses is set aside so that\n\
         # a rerun of `prism farm slurm` renders it again.\n\
         set -euo pipefail\n\
         PRISM={prism}\nOUT={out}\n\
         exec \"$PRISM\" farm merge \"$OUT\"\n",
        prism = shell_word(paths.prism()),
        out = shell_word(paths.outdir()),
    );
    s
}

/// Task IDs as Slurm's array list (`0-3,7,9-10`), throttled by `%K`.
pub fn array_spec(tasks: &[u64], max_running: Option<u32>) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < tasks.len() {
        let mut j = i;
        while j + 1 < tasks.len() && tasks[j + 1] == tasks[j] + 1 {
            j += 1;
        }
        parts.push(if i == j {
            tasks[i].to_string()
        } else {
            format!("{}-{}", tasks[i], tasks[j])
        });
        i = j + 1;
    }
    let mut spec = parts.join(",");
    if let Some(k) = max_running {
        let _ = write!(spec, "%{k}");
    }
    spec
}

/// Runs `sbatch --parsable ARGS` in the output folder (the jobs' working
/// folder, against which their log paths are resolved), without a shell.
fn sbatch(outdir: &Path, args: &[String]) -> Result<String, Failure> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .current_dir(outdir)
        .output()
        .map_err(|e| Failure::Failed(format!("cannot run sbatch: {e}; is Slurm installed?")))?;
    if !out.status.success() {
        return Err(Failure::Failed(format!(
            "sbatch {} failed: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    // `--parsable` prints `ID` or `ID;cluster`.
    let text = String::from_utf8_lossy(&out.stdout);
    let id = text
        .trim()
        .split(';')
        .next()
        .unwrap_or_default()
        .to_string();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        return Err(Failure::Failed(format!("sbatch printed no job ID: {text}")));
    }
    Ok(id)
}

fn record(outdir: &Path, kind: &str, id: &str) -> Result<(), Failure> {
    use std::io::Write;
    let path = outdir.join(JOBS);
    std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .and_then(|mut f| writeln!(f, "{kind} {id}"))
        .map_err(|e| Failure::Failed(format!("{}: {e}", path.display())))
}

fn recorded(outdir: &Path, kind: &str) -> Vec<String> {
    std::fs::read_to_string(outdir.join(JOBS))
        .unwrap_or_default()
        .lines()
        .filter_map(|l| l.strip_prefix(kind)?.strip_prefix(' '))
        .filter(|id| !id.is_empty() && id.bytes().all(|b| b.is_ascii_digit()))
        .map(str::to_string)
        .collect()
}

/// The recorded jobs of `kind` that Slurm has in one of `states`.
fn active_jobs(outdir: &Path, kind: &str, states: &str) -> Vec<String> {
    recorded(outdir, kind)
        .into_iter()
        .filter(|id| {
            Command::new("squeue")
                .args([
                    "--noheader",
                    "--format=%i",
                    "--states",
                    states,
                    "--jobs",
                    id,
                ])
                .output()
                .is_ok_and(|o| o.status.success() && !o.stdout.trim_ascii().is_empty())
        })
        .collect()
}

/// The cluster's MaxArraySize, where `scontrol` can tell.
fn max_array_size() -> Option<u64> {
    let out = Command::new("scontrol")
        .args(["show", "config"])
        .output()
        .ok()?;
    String::from_utf8_lossy(&out.stdout).lines().find_map(|l| {
        let (key, value) = l.split_once('=')?;
        (key.trim() == "MaxArraySize")
            .then(|| value.trim().parse().ok())
            .flatten()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn array_lists_compress_runs() {
        assert_eq!(array_spec(&[0, 1, 2, 3], Some(2)), "0-3%2");
        assert_eq!(array_spec(&[1, 3, 4, 5, 9], None), "1,3-5,9");
        assert_eq!(array_spec(&[7], None), "7");
    }

    #[test]
    fn partitions_are_names_or_refused() {
        assert!(check_partition("gpu").is_ok() && check_partition("a_1.b-2,c").is_ok());
        for bad in ["", "a b", "a\nb", "a;b", "$(x)", "a%j", "é"] {
            assert!(check_partition(bad).is_err(), "{bad:?}");
        }
    }
}

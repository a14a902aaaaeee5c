//! Slurm: the plan as two batch scripts, `render.sbatch` (a job array,
//! task k rendering part k % tiles of frame first + k / tiles) and
//! `merge.sbatch` (merges every frame whose parts are all there), and
//! their submission with `sbatch`, the merge after the array
//! (`--dependency=afterok`).

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use super::{Failure, Plan, Progress, SlurmArgs, plan_in};

/// Submitted job IDs, one `render ID` or `merge ID` line each.
const JOBS: &str = "jobs.txt";

pub fn run(args: &SlurmArgs) -> Result<(), Failure> {
    let plan = plan_in(&args.common)?;
    let outdir = args
        .common
        .output
        .canonicalize()
        .map_err(|e| Failure::Failed(format!("{}: {e}", args.common.output.display())))?;
    let prism = std::env::current_exe()
        .and_then(|p| p.canonicalize())
        .map_err(|e| Failure::Failed(format!("cannot find the prism executable: {e}")))?;
    let write = |name: &str, text: String| {
        let path = outdir.join(name);
        std::fs::write(&path, text).map_err(|e| Failure::Failed(format!("{}: {e}", path.display())))
    };
    write("render.sbatch", render_script(&plan, &outdir, &prism, args))?;
    write("merge.sbatch", merge_script(&plan, &outdir, &prism, args))?;

    if args.submit {
        // A merge still waiting on an array that lost a task would wait for
        // ever: it is replaced by the one submitted now.
        cancel_waiting_merges(&outdir);
        let active = active_jobs(&outdir, "render");
        if !active.is_empty() {
            return Err(Failure::BadInput(format!(
                "render jobs {} of this folder are still queued or running; wait for them \
                 (prism farm status {}) or cancel them with scancel",
                active.join(", "),
                outdir.display()
            )));
        }
    }
    let progress = Progress::of(&plan, &outdir);
    let array = array_spec(&progress.missing_tasks, args.max_running);
    let render_cmd = format!(
        "sbatch --parsable --array={array} {}/render.sbatch",
        outdir.display()
    );
    if progress.missing_tasks.is_empty() && progress.mergeable.is_empty() {
        say!(
            "{}: every frame is merged; nothing to submit",
            outdir.display()
        );
        return Ok(());
    }
    if !args.submit {
        say!(
            "wrote {0}/render.sbatch and {0}/merge.sbatch; to submit:",
            outdir.display()
        );
        if progress.missing_tasks.is_empty() {
            say!("  sbatch {}/merge.sbatch", outdir.display());
        } else {
            say!("  id=$({render_cmd})");
            say!(
                "  sbatch --dependency=afterok:$id {}/merge.sbatch",
                outdir.display()
            );
        }
        return Ok(());
    }
    let mut dependency = Vec::new();
    if !progress.missing_tasks.is_empty() {
        let id = sbatch(&[
            format!("--array={array}"),
            outdir.join("render.sbatch").display().to_string(),
        ])?;
        record(&outdir, "render", &id)?;
        say!(
            "submitted render job {id}: {} tasks ({array})",
            progress.missing_tasks.len()
        );
        dependency.push(format!("--dependency=afterok:{id}"));
    }
    let mut merge_args = dependency;
    merge_args.push(outdir.join("merge.sbatch").display().to_string());
    let id = sbatch(&merge_args)?;
    record(&outdir, "merge", &id)?;
    say!("submitted merge job {id}");
    Ok(())
}

/// Single quotes for the shell.
fn quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

fn directives(args: &SlurmArgs, name: &str, log: &str, outdir: &Path) -> String {
    let mut s = format!(
        "#!/bin/bash\n#SBATCH --job-name={name}\n#SBATCH --output={}/logs/{log}\n",
        outdir.display()
    );
    if let Some(p) = &args.partition {
        let _ = writeln!(s, "#SBATCH --partition={p}");
    }
    if let Some(c) = args.cpus_per_task {
        let _ = writeln!(s, "#SBATCH --cpus-per-task={c}");
    }
    s
}

fn render_script(plan: &Plan, outdir: &Path, prism: &Path, args: &SlurmArgs) -> String {
    let mut s = directives(args, "prism-render", "render_%A_%a.log", outdir);
    let last = plan.task_count() - 1;
    let throttle = args.max_running.map_or(String::new(), |k| format!("%{k}"));
    let _ = write!(
        s,
        "#SBATCH --array=0-{last}{throttle}\n\
         # Written by `prism farm slurm`: task k renders tile k % TILES of frame\n\
         # FIRST + k / TILES into parts/ (written atomically: a part that exists\n\
         # is whole). Rerun `prism farm slurm` to submit only what is missing.\n\
         set -euo pipefail\n\
         PRISM={prism}\nSCENE={scene}\nOUT={out}\nTILES={tiles}\nFIRST={first}\n\
         k=${{SLURM_ARRAY_TASK_ID:?run this script as a Slurm array job}}\n\
         frame=$(( FIRST + k / TILES ))\n\
         tile=$(( k % TILES ))\n\
         part=$(printf '%s/parts/frame_%04d_tile_%04d.exr' \"$OUT\" \"$frame\" \"$tile\")\n\
         echo \"prism farm: task $k frame $frame tile $tile/$TILES on $(hostname)\"\n\
         exec \"$PRISM\" render \"$SCENE\" --frame \"$frame\" --tile \"$tile/$TILES\" -o \"$part\" \\\n\
         \x20   ${{SLURM_CPUS_PER_TASK:+--threads \"$SLURM_CPUS_PER_TASK\"}}\n",
        prism = quote(&prism.display().to_string()),
        scene = quote(&plan.scene.display().to_string()),
        out = quote(&outdir.display().to_string()),
        tiles = plan.tiles,
        first = plan.first_frame,
    );
    s
}

fn merge_script(plan: &Plan, outdir: &Path, prism: &Path, args: &SlurmArgs) -> String {
    let mut s = directives(args, "prism-merge", "merge_%j.log", outdir);
    let _ = write!(
        s,
        "# Written by `prism farm slurm`: merges every frame whose parts are all\n\
         # there and that is not merged yet.\n\
         set -euo pipefail\n\
         PRISM={prism}\nOUT={out}\nTILES={tiles}\n\
         for frame in $(seq {first} {last}); do\n\
         \x20 out=$(printf '%s/frame_%04d.{ext}' \"$OUT\" \"$frame\")\n\
         \x20 [ -e \"$out\" ] && continue\n\
         \x20 parts=()\n\
         \x20 for tile in $(seq 0 $(( TILES - 1 ))); do\n\
         \x20   parts+=(\"$(printf '%s/parts/frame_%04d_tile_%04d.exr' \"$OUT\" \"$frame\" \"$tile\")\")\n\
         \x20 done\n\
         \x20 \"$PRISM\" merge \"${{parts[@]}}\" -o \"$out\"\n\
         \x20 echo \"prism farm: merged frame $frame -> $out\"\n\
         done\n",
        prism = quote(&prism.display().to_string()),
        out = quote(&outdir.display().to_string()),
        tiles = plan.tiles,
        first = plan.first_frame,
        last = plan.last_frame,
        ext = plan.format,
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

fn sbatch(args: &[String]) -> Result<String, Failure> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .args(args)
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
        .map(str::to_string)
        .collect()
}

/// The recorded jobs of `kind` that Slurm still has queued or running.
fn active_jobs(outdir: &Path, kind: &str) -> Vec<String> {
    recorded(outdir, kind)
        .into_iter()
        .filter(|id| {
            Command::new("squeue")
                .args(["--noheader", "--format=%i", "--jobs", id])
                .output()
                .is_ok_and(|o| o.status.success() && !o.stdout.trim_ascii().is_empty())
        })
        .collect()
}

fn cancel_waiting_merges(outdir: &Path) {
    for id in active_jobs(outdir, "merge") {
        let _ = Command::new("scancel").arg(&id).status();
    }
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
}

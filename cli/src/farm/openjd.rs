//! Open Job Description (the job template format of AWS Deadline Cloud;
//! `openjd run` from PyPI's openjd-cli runs one locally): a `Render` step
//! over the task parameters Frame and Tile, each task one
//! `prism render --frame F --tile T/N`, and a `Merge` step over Frame that
//! depends on it.
//!
//! Paths are not written into the template: they are the job's PATH
//! parameters, passed to each task in its environment and quoted wherever
//! the task's shell line uses them.

use std::path::Path;

use serde_json::json;

use super::{Failure, FarmArgs, plan_in, shell_word, write_file};

const BACKEND: &str = "the Open Job Description backend";

/// The template's file name in the output folder.
const TEMPLATE: &str = "job.template.json";

pub fn run(args: &FarmArgs) -> Result<(), Failure> {
    let (plan, paths) = plan_in(args, BACKEND)?;
    let template = template(
        &plan.scene,
        plan.tiles,
        (plan.first_frame, plan.last_frame),
        &plan.format,
    );
    let path = paths.outdir.join(TEMPLATE);
    let text =
        serde_json::to_string_pretty(&template).map_err(|e| Failure::Failed(e.to_string()))?;
    write_file(&path, &(text + "\n"))?;
    say!("wrote {}; to run it here:", path.display());
    say!(
        "  openjd run {} --step Merge --run-dependencies -p {} -p {} -p {}",
        shell_word(path.to_str().unwrap_or_default()),
        shell_word(&format!("Prism={}", paths.prism())),
        shell_word(&format!("Scene={}", paths.scene())),
        shell_word(&format!("OutputDir={}", paths.outdir())),
    );
    Ok(())
}

/// The job template. Parts are named as `prism farm slurm` names them
/// (frame and tile zero-padded to four digits), so the two share an output
/// folder's layout and `prism farm status`.
fn template(scene: &Path, tiles: u32, frames: (u32, u32), format: &str) -> serde_json::Value {
    let part = "$(printf '%s/parts/frame_%04d_tile_%04d.exr' \"$OUT\" \"$FRAME\" \"$TILE\")";
    let render = format!(
        "set -eu; mkdir -p \"$OUT/parts\"; exec \"$PRISM\" render \"$SCENE\" --frame \"$FRAME\" \
         --tile \"$TILE/{tiles}\" -o \"{part}\""
    );
    // The part paths as the positional parameters: each one word, whatever
    // the folder's name holds.
    let merge = format!(
        "set -eu; set --; TILE=0; while [ \"$TILE\" -lt {tiles} ]; do set -- \"$@\" \"{part}\"; \
         TILE=$((TILE + 1)); done; \
         exec \"$PRISM\" merge \"$@\" -o \"$(printf '%s/frame_%04d.{format}' \"$OUT\" \"$FRAME\")\"",
    );
    // Each task runs one shell line with its values in the environment.
    let action = |line: &str, tile: bool| {
        json!({
            "command": "/usr/bin/env",
            "args": [
                "PRISM={{Param.Prism}}",
                "SCENE={{Param.Scene}}",
                "OUT={{Param.OutputDir}}",
                "FRAME={{Task.Param.Frame}}",
                if tile { "TILE={{Task.Param.Tile}}" } else { "TILE=0" },
                "/bin/sh",
                "-c",
                line
            ]
        })
    };
    let frame_range = format!("{}-{}", frames.0, frames.1);
    json!({
        "specificationVersion": "jobtemplate-2023-09",
        // The job name is a format string: only plain characters of the
        // scene's name go into it.
        "name": format!("prism {}", scene.file_name().map_or(String::new(), |n| {
            n.to_string_lossy()
                .chars()
                .map(|c| if c.is_alphanumeric() || "._-".contains(c) { c } else { '_' })
                .collect()
        })),
        "parameterDefinitions": [
            // Default paths may only point below the template's folder, so
            // the executable and the scene are given when the job is run.
            { "name": "Prism", "type": "PATH", "objectType": "FILE", "dataFlow": "IN",
              "description": "the prism executable" },
            { "name": "Scene", "type": "PATH", "objectType": "FILE", "dataFlow": "IN",
              "description": "the scene file" },
            { "name": "OutputDir", "type": "PATH", "objectType": "DIRECTORY", "dataFlow": "OUT",
              "default": "." }
        ],
        "steps": [
            {
                "name": "Render",
                "parameterSpace": {
                    "taskParameterDefinitions": [
                        { "name": "Frame", "type": "INT", "range": frame_range },
                        { "name": "Tile", "type": "INT", "range": format!("0-{}", tiles - 1) }
                    ]
                },
                "script": { "actions": { "onRun": action(&render, true) } }
            },
            {
                "name": "Merge",
                "dependencies": [ { "dependsOn": "Render" } ],
                "parameterSpace": {
                    "taskParameterDefinitions": [
                        { "name": "Frame", "type": "INT", "range": frame_range }
                    ]
                },
                "script": { "actions": { "onRun": action(&merge, false) } }
            }
        ]
    })
}

#!/bin/bash
# Prism and Blender (issue 15, items 8-9): installs Debian's blender and
# python3-numpy (the glTF exporter needs numpy; the package does not pull
# it in) and xvfb when absent, builds prism and the add-on zip, then headless:
#  1. scripts/blender/make_scenes.py builds the probes (a diffuse plane
#     under a point, spot or sun light), Blender's default scene and a
#     showcase (texture transform, mirror, glass, emission, spot);
#  2. each renders through the add-on (`-E PRISM -f 1`, the zip installed
#     as a user would) and must equal `prism render` of the same export
#     (scripts/blender/compare.py);
#  3. each renders in Cycles and the ratio Prism/Cycles at the centre is
#     asserted within 5 % (ASSERT_WITHIN in scripts/blender/cycles_probe.py);
#     with the add-on's "Lights: Scene File" it is asserted within 5 %;
#  4. a render border, an animation, cancel and error reports
#     (scripts/blender/engine_probe.py);
#  5. F12 in Blender's interface under xvfb (scripts/blender/ui_render.py),
#     checked against `prism render` of its export;
#  6. issue 29: the add-on installed by docs/blender.md's headless command;
#     a spot's pool against Cycles' (spot_profile.py), the render's
#     geometry (glb_mesh.py), depth of field (dof_probe.py), a checker
#     floor, lens shift, a newcomer's three scenes, the warnings,
#     "Keep Files In" refused on an unsaved file, objects' motion blur
#     against Cycles (object_motion_probe.py), and no shadow-terminator
#     steps on a smooth low-poly sphere (terminator_probe.py).
# Work files: target/blender-test/. With --update-data the exports are
# copied to tests/data/blender/ (commit them, with the Blender version).
set -euo pipefail
cd "$(dirname "$0")/.."
# xvfb: F12 in Blender's interface renders on a job thread, a path of its
# own; a virtual display lets the test take it.
if ! command -v blender >/dev/null || ! dpkg -s python3-numpy >/dev/null 2>&1 \
    || ! command -v xvfb-run >/dev/null; then
    echo "installing blender, python3-numpy and xvfb from Debian ..." >&2
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq blender python3-numpy xvfb xauth >/dev/null
fi
cargo build --release --locked --quiet
scripts/build-blender-addon.sh >/dev/null
PRISM=$PWD/target/release/prism
ZIP=$PWD/target/prism_render.zip
WORK=$PWD/target/blender-test
rm -rf "$WORK"
mkdir -p "$WORK"
# The add-on is installed here, not into the user's own Blender, and its
# preferences saved here (Debian's Blender 3.4 reads its preferences from
# $XDG_CONFIG_HOME/blender, not from $BLENDER_USER_CONFIG).
export BLENDER_USER_SCRIPTS=$WORK/user-scripts XDG_CONFIG_HOME=$WORK/config
# An add-on folder that exists at start-up is on Blender's module path.
mkdir -p "$BLENDER_USER_SCRIPTS/addons"
blend() { blender --background --python-exit-code 1 "$@" >>"$WORK/blender.log" 2>&1 || {
    echo "blender failed: $*; the end of $WORK/blender.log:" >&2; tail -30 "$WORK/blender.log" >&2; exit 1; }; }
start=$(date +%s)
blender --version | head -1
# The headless install of docs/blender.md ("Install"), word for word: the
# renders below use the preferences it saves (use_addon.py checks them).
blender -b --python-expr "import bpy, sys; zip_path, prism = sys.argv[sys.argv.index('--') + 1:]; \
bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True); \
bpy.ops.preferences.addon_enable(module='prism_render'); \
bpy.context.preferences.addons['prism_render'].preferences.prism_path = prism; \
bpy.ops.wm.save_userpref()" -- "$ZIP" "$PRISM" >>"$WORK/blender.log" 2>&1
blend --factory-startup --python scripts/blender/make_scenes.py -- "$WORK"
# Prints the lines of $WORK/blender.log from line $1 on that start with $2.
since() { tail -n "+$1" "$WORK/blender.log" | grep "^$2" || true; }
for name in probe_point probe_spot probe_sun probe_area probe_area_disk probe_area45 probe_spot_profile probe_furnace motion_camera motion_object \
        default default_ortho default_portrait default_shift default_ortho_shift showcase \
        newcomer_checker newcomer_dof newcomer_spot newcomer_area newcomer_area_side; do
    dir=$WORK/$name
    mkdir -p "$dir"
    spp=1
    case $name in default*|showcase|newcomer_*) spp=4 ;; esac
    # A lens or a shutter wants samples; the pinhole newcomer_checker as many as
    # newcomer_dof (and Cycles there): dof_probe.py compares them at equal noise.
    case $name in newcomer_checker|newcomer_dof|motion_*) spp=16 ;; esac
    # Through the add-on, as `blender -b FILE -E PRISM -f 1` does.
    blend "$WORK/$name.blend" --python scripts/blender/use_addon.py \
        -E PRISM -o "$dir/blender_#" -f 1 -- "$ZIP" "$PRISM" "$dir/export" "$spp"
    if [ ! -f "$dir/blender_1.exr" ]; then
        echo "FAIL: $name: the add-on rendered nothing; $WORK/blender.log says:" >&2
        grep -i "error" "$WORK/blender.log" | tail -10 >&2
        exit 1
    fi
    "$PRISM" render "$dir/export/scene.toml" -o "$dir/prism.exr" --quiet
    blend --factory-startup --python scripts/blender/compare.py -- "$dir/blender_1.exr" "$dir/prism.exr"
    grep "^compare:" "$WORK/blender.log" | tail -1 | sed "s/^/$name: /"
    mark=$(( $(wc -l <"$WORK/blender.log") + 1 ))
    blend "$WORK/$name.blend" --python scripts/blender/cycles_probe.py -- "$dir/prism.exr" "$dir" "$name"
    since "$mark" "cycles_probe:"
    case $name in probe_*|default) ;; *) continue ;; esac
    # Lights: Scene File: the add-on writes the lights in its own units,
    # matched to Cycles: asserted within 5 % on the probes now.
    blend "$WORK/$name.blend" --python scripts/blender/use_addon.py \
        -E PRISM -o "$dir/scene_lights_#" -f 1 -- "$ZIP" "$PRISM" "$dir/export-scene-lights" "$spp" - SCENE
    tolerance=()
    [ "$name" = default ] || tolerance=(0.05)
    mark=$(( $(wc -l <"$WORK/blender.log") + 1 ))
    blend "$WORK/$name.blend" --python scripts/blender/cycles_probe.py -- \
        "$dir/scene_lights_1.exr" "$dir" "$name (Lights: Scene File)" "${tolerance[@]}"
    since "$mark" "cycles_probe:"
done
# Issue 29. The spot's pool as Cycles lights it: its core and
# half-brightness widths within 3 % of Cycles', in either lights mode.
mark=$(( $(wc -l <"$WORK/blender.log") + 1 ))
for image in prism scene_lights_1; do
    blend --factory-startup --python scripts/blender/spot_profile.py -- \
        "$WORK/probe_spot_profile/cycles.exr" "$WORK/probe_spot_profile/$image.exr" "spot ($image)"
done
since "$mark" "spot_profile:"
# The render's geometry: the cube's Subdivision modifier (viewport 0,
# render 2) exported at level 2: 6 x 16 quads, 98 vertices;
python3 scripts/blender/glb_mesh.py "$WORK/newcomer_spot/export/scene.glb" "subdivided cube" 192 98
# and the emitting ball, disabled in viewports but not in renders (a UV
# sphere of 32 segments and 16 rings: 960 triangles, 482 vertices).
python3 scripts/blender/glb_mesh.py "$WORK/newcomer_spot/export/scene.glb" emitter 960 482
# Depth of field: blurred out of focus as Cycles blurs it, sharp in focus
# (pinhole and lens at equal samples and pixel filter), the lens as Cycles
# reads Blender's camera.
mark=$(( $(wc -l <"$WORK/blender.log") + 1 ))
blend "$WORK/newcomer_dof.blend" --python scripts/blender/dof_probe.py -- \
    "$WORK/newcomer_checker/cycles.exr" "$WORK/newcomer_checker/prism.exr" \
    "$WORK/newcomer_dof/cycles.exr" "$WORK/newcomer_dof/prism.exr" "$WORK/newcomer_dof/export/scene.toml"
since "$mark" "dof_probe:"
# Camera motion blur: the camera's smear as Cycles smears it.
mark=$(( $(wc -l <"$WORK/blender.log") + 1 ))
blend --factory-startup --python scripts/blender/motion_probe.py -- \
    "$WORK/motion_camera/cycles.exr" "$WORK/motion_camera/prism.exr"
since "$mark" "motion_probe:"
# Object motion blur: a ball moving sideways streaks as in Cycles and as
# the analytic travel + diameter (a glTF animation the add-on writes).
mark=$(( $(wc -l <"$WORK/blender.log") + 1 ))
blend --factory-startup --python scripts/blender/object_motion_probe.py -- \
    "$WORK/motion_object/cycles.exr" "$WORK/motion_object/prism.exr"
since "$mark" "object_motion_probe:"
# The shadow terminator: a smooth 32-segment UV sphere under a side sun
# shades as the sphere its normals describe (within 2 % of E*N.L up to
# the terminator, never darker along the meridian towards the light).
term=$WORK/terminator
mkdir -p "$term"
blend --factory-startup --python scripts/blender/terminator_probe.py -- make "$term/terminator.blend"
blend "$term/terminator.blend" --python scripts/blender/use_addon.py \
    -E PRISM -o "$term/prism_#" -f 1 -- "$ZIP" "$PRISM" "$term/export" 1
blend "$term/terminator.blend" -E CYCLES -o "$term/cycles_#" -f 1
mark=$(( $(wc -l <"$WORK/blender.log") + 1 ))
blend --factory-startup --python scripts/blender/terminator_probe.py -- \
    measure "$term/prism_1.exr" "$term/cycles_1.exr"
since "$mark" "terminator_probe:"
# What Prism cannot show is said, once each: the nodes the export drops
# (a Noise Texture on the cube, a checker on a cube's Generated
# coordinates), a sun's angle, a spot's radius; the rigid motion of
# objects (the rising emitter, the moving ball) is carried, not warned of.
if grep -q "rendered sharp" "$WORK/blender.log"; then
    echo "FAIL: an object's motion is still rendered sharp:" >&2
    grep "rendered sharp" "$WORK/blender.log" >&2
    exit 1
fi
for warning in "material 'vertex colours': the glTF export drops Noise Texture" \
        "material 'box': the glTF export drops Checker Texture" \
        "light 'sun': a sun's angle is not carried" \
        "light 'spot light': a spot's radius is not carried"; do
    if ! grep -qF "$warning" "$WORK/blender.log"; then
        echo "FAIL: no warning \"$warning\" in $WORK/blender.log" >&2
        exit 1
    fi
done
# "Keep Files In" relative on an unsaved file is refused, not the working directory.
unsaved=$WORK/unsaved
mkdir -p "$unsaved"
(cd "$unsaved" && blender -b --python-expr "import bpy, sys
scene = bpy.context.scene
scene.render.engine = 'PRISM'
scene.prism.export_dir = 'kept'
try:
    bpy.ops.render.render()
except RuntimeError as e:
    print('unsaved:', e)" >>"$WORK/blender.log" 2>&1) || true  # Blender exits 1 after the error
if [ -e "$unsaved/kept" ] || ! grep -q "^unsaved:.*not saved yet" "$WORK/blender.log"; then
    echo "FAIL: Keep Files In on an unsaved file was not refused" >&2
    exit 1
fi
echo "unsaved file: Keep Files In refused"
# A render border (cropped): Prism renders the border alone, and it must be
# that part of the whole frame's render above.
border=$WORK/border
mkdir -p "$border"
blend "$WORK/default.blend" --python scripts/blender/use_addon.py --python-expr "import bpy
r = bpy.context.scene.render
r.use_border, r.use_crop_to_border = True, True
r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.25, 0.75, 0.5, 1.0" \
    -E PRISM -o "$border/blender_#" -f 1 -- "$ZIP" "$PRISM" "$border/export" 4
blend --factory-startup --python scripts/blender/compare.py -- \
    "$border/blender_1.exr" "$WORK/default/blender_1.exr" 16,48,18,36
grep "^compare:" "$WORK/blender.log" | tail -1 | sed "s/^/border: /"
# An animation (-a): each frame is exported in its own pose.
anim=$WORK/anim
mkdir -p "$anim"
blend "$WORK/default_anim.blend" --python scripts/blender/use_addon.py \
    -E PRISM -o "$anim/frame_#" -a -- "$ZIP" "$PRISM" "$anim/export" 1
"$PRISM" render "$anim/export/scene.toml" -o "$anim/prism.exr" --quiet
blend --factory-startup --python scripts/blender/compare.py -- "$anim/frame_3.exr" "$anim/prism.exr"
blend --factory-startup --python scripts/blender/compare.py -- --differ "$anim/frame_1.exr" "$anim/frame_3.exr"
grep "^compare:" "$WORK/blender.log" | tail -2 | sed "s/^/animation: /"
# Cancel once tiles are shown; Prism's error reaches Blender's reports.
blend "$WORK/probe_point.blend" --python scripts/blender/use_addon.py \
    --python scripts/blender/engine_probe.py -- "$ZIP" "$PRISM" "$WORK/engine" 1
grep "^engine_probe:" "$WORK/blender.log"
# F12 in the interface (under a virtual display): the add-on runs on the
# render job's thread and hands the export to the main thread.
ui=$WORK/ui
mkdir -p "$ui"
timeout 300 xvfb-run -a -s "-screen 0 1280x800x24" blender \
    "$WORK/default.blend" --python scripts/blender/use_addon.py --python scripts/blender/ui_render.py \
    -- "$ZIP" "$PRISM" "$ui/export" 4 "$ui/f12.exr" >>"$WORK/blender.log" 2>&1 || true
grep "^ui_render:" "$WORK/blender.log" || true
if [ ! -f "$ui/f12.exr" ]; then
    echo "FAIL: F12 in the interface rendered nothing; see $WORK/blender.log" >&2
    exit 1
fi
"$PRISM" render "$ui/export/scene.toml" -o "$ui/prism.exr" --quiet
blend --factory-startup --python scripts/blender/compare.py -- "$ui/f12.exr" "$ui/prism.exr"
grep "^compare:" "$WORK/blender.log" | tail -1 | sed "s/^/F12: /"
if [ "${1:-}" = "--update-data" ]; then
    version=$(blender --version | head -1)
    for name in probe_point probe_spot probe_sun default default_ortho default_portrait showcase; do
        cp "$WORK/$name/export/scene.glb" "tests/data/blender/$name.glb"
    done
    cp "$WORK/default/side_by_side_scene_lights_1.png" docs/images/blender-default.png
    echo "tests/data/blender/ and docs/images/blender-default.png updated ($version)"
fi
echo "test-blender: ok in $(( $(date +%s) - start )) s (the log: $WORK/blender.log)"

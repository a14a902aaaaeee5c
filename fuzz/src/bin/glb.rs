//! AFL harness for the `glb` target (see fuzz/src/targets.rs).
fn main() {
    afl::fuzz!(|data: &[u8]| prism_fuzz::run("glb", data));
}

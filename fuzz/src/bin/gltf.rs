//! AFL harness for the `gltf` target (see fuzz/src/targets.rs).
fn main() {
    afl::fuzz!(|data: &[u8]| prism_fuzz::run("gltf", data));
}

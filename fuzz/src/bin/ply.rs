//! AFL harness for the `ply` target (see fuzz/src/targets.rs).
fn main() {
    afl::fuzz!(|data: &[u8]| prism_fuzz::run("ply", data));
}

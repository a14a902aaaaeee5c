//! AFL harness for the `obj` target (see fuzz/src/targets.rs).
fn main() {
    afl::fuzz!(|data: &[u8]| prism_fuzz::run("obj", data));
}

//! AFL harness for the `image` target (see fuzz/src/targets.rs).
fn main() {
    afl::fuzz!(|data: &[u8]| prism_fuzz::run("image", data));
}

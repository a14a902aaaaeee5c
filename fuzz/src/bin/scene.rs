//! AFL harness for the `scene` target (see fuzz/src/targets.rs).
fn main() {
    afl::fuzz!(|data: &[u8]| {
        #[cfg(feature = "planted")]
        prism_fuzz::planted(data);
        prism_fuzz::run("scene", data);
    });
}

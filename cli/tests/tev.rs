//! `--display-server`: a stand-in for tev listens, decodes the packets of
//! its protocol (create image, then update-image tiles) and reassembles
//! the picture, which must equal the EXR `prism render` writes.

use std::io::Read;
use std::net::TcpListener;
use std::process::Command;

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

/// A zero-terminated string at `*at`, advancing past it.
fn string(b: &[u8], at: &mut usize) -> String {
    let end = *at + b[*at..].iter().position(|&c| c == 0).unwrap();
    let s = String::from_utf8(b[*at..end].to_vec()).unwrap();
    *at = end + 1;
    s
}

#[test]
fn tiles_reach_tev_and_make_up_the_picture() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let received = std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        let mut all = Vec::new();
        s.read_to_end(&mut all).unwrap();
        all
    });
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("out.exr");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/whitted.toml");
    let o = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args([
            "render",
            scene,
            "--width",
            "50",
            "--height",
            "37",
            "-q",
            "--display-server",
            &address,
            "-o",
        ])
        .arg(&exr)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = received.join().unwrap();

    let (mut at, mut picture, mut size, mut tiles) = (0, Vec::new(), (0, 0), 0);
    while at < bytes.len() {
        let len = u32_at(&bytes, at) as usize;
        let p = &bytes[at..at + len];
        let mut i = 5;
        match p[4] {
            4 => {
                assert_eq!(p[5], 1);
                i += 1;
                assert!(string(p, &mut i).ends_with("out.exr"));
                size = (u32_at(p, i) as usize, u32_at(p, i + 4) as usize);
                assert_eq!(u32_at(p, i + 8), 3);
                i += 12;
                let names: Vec<String> = (0..3).map(|_| string(p, &mut i)).collect();
                assert_eq!(names, ["R", "G", "B"]);
                picture = vec![f32::NAN; size.0 * size.1 * 3];
            }
            6 => {
                i += 1;
                string(p, &mut i);
                assert_eq!(u32_at(p, i), 3);
                i += 4;
                for _ in 0..3 {
                    string(p, &mut i);
                }
                let [x, y, w, h] = [0, 4, 8, 12].map(|k| u32_at(p, i + k) as usize);
                i += 16 + 48; // offsets and strides (3 + 3 i64)
                for row in 0..h {
                    for col in 0..w {
                        for c in 0..3 {
                            let k = i + ((row * w + col) * 3 + c) * 4;
                            let v = f32::from_le_bytes(p[k..k + 4].try_into().unwrap());
                            picture[((y + row) * size.0 + x + col) * 3 + c] = v;
                        }
                    }
                }
                tiles += 1;
            }
            other => panic!("unexpected packet type {other}"),
        }
        at += len;
    }
    assert_eq!(size, (50, 37));
    assert_eq!(tiles, 4 * 3);
    let written = image::open(&exr).unwrap().to_rgb32f();
    let expected: Vec<f32> = written.pixels().flat_map(|p| p.0).collect();
    assert_eq!(picture, expected, "tev's picture is the EXR's, bit for bit");

    // No tev listening: a clear message, exit 2, nothing rendered.
    let closed = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .to_string();
    let o = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args(["render", scene, "--display-server", &closed, "-o"])
        .arg(dir.path().join("x.png"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot connect to tev"));
}

//! `prism serve` over HTTP, as a page sees it: the server on port 0, its
//! Host check, the event stream (a coarse picture first, then tiles, then
//! done), a save that cancels the render under way and restarts it, a
//! broken scene reported as located errors while the last good picture
//! stays, and the saved image equal to `prism render`'s.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Server {
    child: Child,
    addr: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn serve(scene: &Path) -> Server {
    let mut child = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args(["serve", scene.to_str().unwrap(), "--port", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let addr = line
        .split("http://")
        .nth(1)
        .and_then(|r| r.split('/').next())
        .unwrap_or_else(|| panic!("no URL in {line:?}"))
        .to_string();
    Server { child, addr }
}

/// A GET with the given Host header: (status, body).
fn get(addr: &str, path: &str, host: &str) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut all = Vec::new();
    s.read_to_end(&mut all).unwrap();
    let split = all.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    let head = String::from_utf8_lossy(&all[..split]).to_string();
    let status = head.split(' ').nth(1).unwrap().parse().unwrap();
    let mut body = all[split + 4..].to_vec();
    if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        body = dechunk(&body);
    }
    (status, body)
}

fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let end = b.windows(2).position(|w| w == b"\r\n").unwrap();
        let size =
            usize::from_str_radix(std::str::from_utf8(&b[..end]).unwrap().trim(), 16).unwrap();
        if size == 0 {
            return out;
        }
        out.extend_from_slice(&b[end + 2..end + 2 + size]);
        b = &b[end + 2 + size + 2..];
    }
}

/// The event stream: (name, JSON) pairs as they come.
struct Events(BufReader<TcpStream>);

impl Events {
    fn open(addr: &str) -> Events {
        let mut s = TcpStream::connect(addr).unwrap();
        write!(s, "GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        let mut r = BufReader::new(s);
        let mut line = String::new();
        while r.read_line(&mut line).unwrap() > 0 && line != "\r\n" {
            line.clear();
        }
        Events(r)
    }

    fn next(&mut self) -> (String, serde_json::Value) {
        let (mut name, mut data) = (String::new(), String::new());
        loop {
            let mut line = String::new();
            assert!(self.0.read_line(&mut line).unwrap() > 0, "stream closed");
            let line = line.trim_end();
            if let Some(n) = line.strip_prefix("event:") {
                name = n.trim().to_string();
            } else if let Some(d) = line.strip_prefix("data:") {
                data.push_str(d.trim_start());
            } else if line.is_empty() && !name.is_empty() {
                return (name, serde_json::from_str(&data).unwrap_or_default());
            }
            // Chunk sizes of the chunked encoding and keep-alive comments
            // are skipped.
        }
    }

    /// Events until a status with `phase`, returning the names seen.
    fn until(&mut self, phase: &str) -> (Vec<(String, String)>, serde_json::Value) {
        let mut seen = Vec::new();
        loop {
            let (name, data) = self.next();
            let tag = data["pass"]
                .as_str()
                .or(data["phase"].as_str())
                .unwrap_or("")
                .to_string();
            seen.push((name.clone(), tag));
            if name == "status" && data["phase"] == phase {
                return (seen, data);
            }
        }
    }
}

const SCENE: &str = r#"
[render]
width = 96
height = 72
spp = 4
[camera]
position = [0, 1, 6]
look_at = [0, 0.8, 0]
[materials.red]
color = [1, 0.1, 0.1]
[materials.floor]
color = [0.9, 0.9, 0.9]
[lights.key]
type = "sphere"
position = [3, 5, 4]
radius = 0.5
samples = 16
[[objects]]
type = "plane"
name = "floor"
material = "floor"
normal = [0, 1, 0]
distance = 0
[[objects]]
type = "sphere"
name = "ball"
material = "red"
center = [0, 1, 0]
radius = 1
"#;

fn render_png(dir: &Path, scene: &str) -> Vec<u8> {
    let out = dir.join("reference.png");
    let o = Command::new(env!("CARGO_BIN_EXE_prism"))
        .args(["render", scene, "-q", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success());
    std::fs::read(out).unwrap()
}

#[test]
fn the_preview_streams_follows_saves_and_reports_errors() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, SCENE).unwrap();
    let server = serve(&scene);
    let addr = server.addr.as_str();

    // Only our own Host is served (DNS rebinding).
    assert_eq!(get(addr, "/", "evil.example").0, 421);
    let (status, page) = get(addr, "/", addr);
    assert_eq!(status, 200);
    let page = String::from_utf8(page).unwrap();
    assert!(page.contains("/app.js") && !page.contains("https://") && !page.contains("http://"));
    let port = addr.rsplit(':').next().unwrap();
    assert_eq!(get(addr, "/", &format!("localhost:{port}")).0, 200);
    // No file from disk.
    assert_eq!(get(addr, "/scene.toml", addr).0, 404);

    // The first render (it may have finished before the stream opened).
    let mut events = Events::open(addr);
    let (_, done) = events.until("done");
    assert!(done["summary"].as_str().unwrap().contains("rays"));
    let reference = render_png(dir.path(), scene.to_str().unwrap());
    assert!(
        get(addr, "/save.png", addr).1 == reference,
        "the preview's final image is the render's"
    );

    // A save: a new generation renders the moved ball.
    let moved = SCENE.replace("center = [0, 1, 0]", "center = [1, 1, 0]");
    std::fs::write(&scene, &moved).unwrap();
    // A coarse picture, then tiles at 1 sample, then at 4, in that order.
    let (seen, done) = events.until("done");
    let at = |name: &str, tag: &str| seen.iter().position(|(n, t)| n == name && t == tag);
    let (coarse, preview) = (at("frame", "coarse"), at("tile", "preview"));
    let last = seen.iter().rposition(|(n, t)| n == "tile" && t == "final");
    assert!(
        coarse.is_some() && coarse < preview && preview < last,
        "{seen:?}"
    );
    assert!(done["first_picture_s"].as_f64().unwrap() < 5.0);
    let reference2 = render_png(dir.path(), scene.to_str().unwrap());
    assert!(reference2 != reference);
    assert!(get(addr, "/save.png", addr).1 == reference2);

    // A broken save: located errors as data; the last good picture stays.
    std::fs::write(&scene, moved.replace("radius = 1\n", "radius = -1\n")).unwrap();
    let (_, error) = events.until("error");
    let e = &error["errors"][0];
    // The ball's radius: line 29, column 10 of SCENE.
    assert_eq!(
        (e["line"].as_u64(), e["column"].as_u64()),
        (Some(29), Some(10)),
        "{error}"
    );
    assert!(e["message"].as_str().unwrap().contains("radius"), "{error}");
    assert!(get(addr, "/save.png", addr).1 == reference2);
    let (_, picture) = get(addr, "/picture", addr);
    let picture: serde_json::Value = serde_json::from_slice(&picture).unwrap();
    assert_eq!(picture["width"], 96);

    // Fixed again: the picture returns.
    std::fs::write(&scene, &moved).unwrap();
    events.until("done");
    assert!(get(addr, "/save.png", addr).1 == reference2);

    // The inspector's tree is explain's.
    let (status, body) = get(addr, "/explain?x=48&y=40", addr);
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    let tree: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(tree["tree"]["kind"], "camera");
    assert!(!tree["segments"].as_array().unwrap().is_empty());
    assert_eq!(get(addr, "/explain?x=999&y=0", addr).0, 400);
    assert_eq!(get(addr, "/aov.png?name=depth", addr).0, 200);
    assert_eq!(get(addr, "/aov.png?name=nope", addr).0, 400);
}

#[test]
fn a_save_stops_the_render_under_way_quickly() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    // Slow: 640x480 at 64 samples with a 16-feeler light (seconds).
    let slow = SCENE.replace(
        "width = 96\nheight = 72\nspp = 4",
        "width = 640\nheight = 480\nspp = 64",
    );
    std::fs::write(&scene, &slow).unwrap();
    let server = serve(&scene);
    let mut events = Events::open(&server.addr);
    events.until("final");
    std::thread::sleep(Duration::from_millis(300));
    let saved = Instant::now();
    std::fs::write(
        &scene,
        slow.replace("center = [0, 1, 0]", "center = [0.5, 1, 0]"),
    )
    .unwrap();
    let (_, status) = events.until("coarse");
    let latency = saved.elapsed();
    assert!(status["generation"].as_u64().unwrap() >= 2);
    // Cancel (a row of a tile), reload and a 1/8 coarse pass: well under a second.
    assert!(
        latency < Duration::from_millis(1500),
        "{latency:?} from save to the new coarse pass"
    );
}

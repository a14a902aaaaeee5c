//! `--display-server HOST:PORT`: streams tiles to the tev image viewer
//! over its TCP protocol, as pbrt-v4 and Mitsuba do. Each packet is a
//! little-endian u32 length (of the whole packet), a type byte and its
//! fields; strings end with a zero byte. Prism sends "create image"
//! (type 4: R, G, B channels) once per image and "update image" (type 6,
//! version 3: a rectangle of interleaved f32 RGB) per finished tile.

use std::io::Write;
use std::net::TcpStream;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use prism::render::Region;

/// A connection to tev, shared by the render threads.
pub struct Tev {
    stream: Mutex<TcpStream>,
    name: String,
    /// Set once a send failed (tev closed): stop trying, warn once.
    failed: AtomicBool,
}

const CREATE_IMAGE: u8 = 4;
const UPDATE_IMAGE_V3: u8 = 6;
const CHANNELS: [&str; 3] = ["R", "G", "B"];

impl Tev {
    /// Connects to tev at `address` (`HOST:PORT`); the image will be
    /// called `name`.
    pub fn connect(address: &str, name: &str) -> Result<Tev, String> {
        let stream = TcpStream::connect(address)
            .map_err(|e| format!("cannot connect to tev at {address}: {e}"))?;
        let _ = stream.set_nodelay(true);
        Ok(Tev {
            stream: Mutex::new(stream),
            name: name.replace('\0', ""),
            failed: AtomicBool::new(false),
        })
    }

    /// Opens a black `width` × `height` RGB image in tev.
    pub fn create(&self, width: u32, height: u32) {
        let mut p = Packet::new(CREATE_IMAGE);
        p.byte(1); // grab focus
        p.string(&self.name);
        p.i32(width as i32);
        p.i32(height as i32);
        p.i32(CHANNELS.len() as i32);
        for c in CHANNELS {
            p.string(c);
        }
        self.send(p);
    }

    /// Sends a finished tile (its pixels row-major).
    pub fn update(&self, tile: Region, pixels: &[DVec3]) {
        let mut p = Packet::new(UPDATE_IMAGE_V3);
        p.byte(0); // do not grab focus
        p.string(&self.name);
        p.i32(CHANNELS.len() as i32);
        for c in CHANNELS {
            p.string(c);
        }
        for v in [tile.x0, tile.y0, tile.width(), tile.height()] {
            p.i32(v as i32);
        }
        // Interleaved RGB: channel c starts at c and steps by 3.
        for offset in 0..3i64 {
            p.0.extend_from_slice(&offset.to_le_bytes());
        }
        for _ in 0..3 {
            p.0.extend_from_slice(&3i64.to_le_bytes());
        }
        for px in pixels {
            for c in px.to_array() {
                p.0.extend_from_slice(&prism::image_io::to_f32(c).to_le_bytes());
            }
        }
        self.send(p);
    }

    fn send(&self, p: Packet) {
        if self.failed.load(Ordering::Relaxed) {
            return;
        }
        let bytes = p.finish();
        let mut stream = self.stream.lock().unwrap_or_else(|e| e.into_inner());
        if let Err(e) = stream.write_all(&bytes)
            && !self.failed.swap(true, Ordering::Relaxed)
        {
            say_err!("warning: tev stopped listening ({e}); the render goes on without it");
        }
    }
}

/// A packet under construction: 4 bytes for the length, then the type.
struct Packet(Vec<u8>);

impl Packet {
    fn new(kind: u8) -> Packet {
        Packet(vec![0, 0, 0, 0, kind])
    }

    fn byte(&mut self, b: u8) {
        self.0.push(b);
    }

    fn i32(&mut self, v: i32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    fn string(&mut self, s: &str) {
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
    }

    fn finish(mut self) -> Vec<u8> {
        let len = self.0.len() as u32;
        self.0[..4].copy_from_slice(&len.to_le_bytes());
        self.0
    }
}

//! Joins PNG frames into one animated PNG (APNG), for the README's picture
//! of `scenes/rolling.toml`.
//!
//! Usage: cargo run --release --example apng -- FPS OUT.png FRAME.png...

use std::fs::File;
use std::io::BufWriter;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [fps, out, frames @ ..] = &args[..] else {
        return Err("usage: apng FPS OUT.png FRAME.png...".into());
    };
    let fps: u16 = fps.parse()?;
    let mut decoded = Vec::new();
    for path in frames {
        let mut reader =
            png::Decoder::new(std::io::BufReader::new(File::open(path)?)).read_info()?;
        let mut buf = vec![0; reader.output_buffer_size().ok_or("frame too large")?];
        let info = reader.next_frame(&mut buf)?;
        buf.truncate(info.buffer_size());
        decoded.push((info.width, info.height, info.color_type, buf));
    }
    let (width, height, color, _) = decoded.first().ok_or("no frames")?.clone();
    let mut encoder = png::Encoder::new(BufWriter::new(File::create(out)?), width, height);
    encoder.set_color(color);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_animated(decoded.len() as u32, 0)?;
    encoder.set_frame_delay(1, fps)?;
    let mut writer = encoder.write_header()?;
    for (w, h, c, data) in &decoded {
        if (*w, *h, *c) != (width, height, color) {
            return Err("frames differ in size or colour type".into());
        }
        writer.write_image_data(data)?;
    }
    writer.finish()?;
    Ok(())
}

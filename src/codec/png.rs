//! A minimal PNG writer: 8-bit grayscale or RGB, no interlace, filter 0 on every row (zlib and
//! CRC-32 come from flate2). Enough for volume previews in a browser.

use std::io::Write;

/// One byte a pixel, rows from the top.
pub fn encode_gray(width: u32, height: u32, pixels: &[u8]) -> Vec<u8> {
    encode(width, height, pixels, 1)
}

/// Three bytes (R, G, B) a pixel, rows from the top.
pub fn encode_rgb(width: u32, height: u32, pixels: &[u8]) -> Vec<u8> {
    encode(width, height, pixels, 3)
}

fn encode(width: u32, height: u32, pixels: &[u8], channels: usize) -> Vec<u8> {
    assert_eq!(
        pixels.len(),
        channels * width as usize * height as usize,
        "pixel count"
    );
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::with_capacity(13);
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    // depth 8, grayscale (0) or RGB (2), deflate, filter 0, no interlace
    ihdr.extend_from_slice(&[8, if channels == 3 { 2 } else { 0 }, 0, 0, 0]);
    chunk(&mut out, b"IHDR", &ihdr);
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    for row in pixels.chunks_exact(channels * width.max(1) as usize) {
        z.write_all(&[0]).expect("memory");
        z.write_all(row).expect("memory");
    }
    chunk(&mut out, b"IDAT", &z.finish().expect("memory"));
    chunk(&mut out, b"IEND", &[]);
    out
}

fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    out.extend_from_slice(kind);
    out.extend_from_slice(data);
    let mut crc = flate2::Crc::new();
    crc.update(kind);
    crc.update(data);
    out.extend_from_slice(&crc.sum().to_be_bytes());
}

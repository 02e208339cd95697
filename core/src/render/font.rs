//! A 5x7 bitmap font for labels and plot annotations: digits, A–Z (lowercase letters use the same glyphs),
//! space and `.,:;%-+=()[]<>/_#!?'*|`. Unknown characters draw as `?`.

use image::RgbImage;

/// Glyph cell size in font pixels (multiplied by the `scale` argument).
pub const GLYPH_WIDTH: u32 = 5;
pub const GLYPH_HEIGHT: u32 = 7;
/// Horizontal advance per character and vertical advance per line, in font pixels.
pub const ADVANCE: u32 = 6;
pub const LINE_HEIGHT: u32 = 9;

/// Rows top to bottom; bit 4 is the leftmost column.
#[rustfmt::skip]
const GLYPHS: &[(char, [u8; 7])] = &[
    ('0', [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110]),
    ('1', [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('2', [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111]),
    ('3', [0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110]),
    ('4', [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010]),
    ('5', [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110]),
    ('6', [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110]),
    ('7', [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000]),
    ('8', [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110]),
    ('9', [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100]),
    ('A', [0b01110, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001]),
    ('B', [0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110]),
    ('C', [0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110]),
    ('D', [0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100]),
    ('E', [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111]),
    ('F', [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000]),
    ('G', [0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111]),
    ('H', [0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001]),
    ('I', [0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110]),
    ('J', [0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100]),
    ('K', [0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001]),
    ('L', [0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111]),
    ('M', [0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001]),
    ('N', [0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001]),
    ('O', [0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110]),
    ('P', [0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000]),
    ('Q', [0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101]),
    ('R', [0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001]),
    ('S', [0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110]),
    ('T', [0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100]),
    ('U', [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110]),
    ('V', [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100]),
    ('W', [0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010]),
    ('X', [0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001]),
    ('Y', [0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100, 0b00100]),
    ('Z', [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111]),
    (' ', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000]),
    ('.', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b01100]),
    (',', [0b00000, 0b00000, 0b00000, 0b00000, 0b01100, 0b00100, 0b01000]),
    (':', [0b00000, 0b01100, 0b01100, 0b00000, 0b01100, 0b01100, 0b00000]),
    (';', [0b00000, 0b01100, 0b01100, 0b00000, 0b01100, 0b00100, 0b01000]),
    ('%', [0b11001, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b10011]),
    ('-', [0b00000, 0b00000, 0b00000, 0b11111, 0b00000, 0b00000, 0b00000]),
    ('+', [0b00000, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0b00000]),
    ('=', [0b00000, 0b00000, 0b11111, 0b00000, 0b11111, 0b00000, 0b00000]),
    ('(', [0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010]),
    (')', [0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000]),
    ('[', [0b01110, 0b01000, 0b01000, 0b01000, 0b01000, 0b01000, 0b01110]),
    (']', [0b01110, 0b00010, 0b00010, 0b00010, 0b00010, 0b00010, 0b01110]),
    ('<', [0b00010, 0b00100, 0b01000, 0b10000, 0b01000, 0b00100, 0b00010]),
    ('>', [0b01000, 0b00100, 0b00010, 0b00001, 0b00010, 0b00100, 0b01000]),
    ('/', [0b00001, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b10000]),
    ('_', [0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b00000, 0b11111]),
    ('#', [0b01010, 0b01010, 0b11111, 0b01010, 0b11111, 0b01010, 0b01010]),
    ('!', [0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00000, 0b00100]),
    ('?', [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b00000, 0b00100]),
    ('\'', [0b00100, 0b00100, 0b01000, 0b00000, 0b00000, 0b00000, 0b00000]),
    ('*', [0b00000, 0b00100, 0b10101, 0b01110, 0b10101, 0b00100, 0b00000]),
    ('|', [0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100]),
];

fn glyph(c: char) -> [u8; 7] {
    let c = c.to_ascii_uppercase();
    GLYPHS
        .iter()
        .find(|(g, _)| *g == c)
        .or_else(|| GLYPHS.iter().find(|(g, _)| *g == '?'))
        .map(|(_, bits)| *bits)
        .unwrap_or([0; 7])
}

/// Sets one pixel if it lies inside the image.
#[inline]
pub(crate) fn put(img: &mut RgbImage, x: i64, y: i64, color: [u8; 3]) {
    if x >= 0 && y >= 0 && x < img.width() as i64 && y < img.height() as i64 {
        img.put_pixel(x as u32, y as u32, image::Rgb(color));
    }
}

/// Draws `text` with its top-left corner at `(x, y)`, each font pixel a `scale x scale` square (`scale` 0 acts as
/// 1). `\n` starts a new line. Pixels outside the image are clipped. Returns the drawn size `(width, height)` in
/// pixels, as [`text_size`].
pub fn draw_text(
    img: &mut RgbImage,
    x: i32,
    y: i32,
    text: &str,
    color: [u8; 3],
    scale: u32,
) -> (u32, u32) {
    draw(img, x as i64, y as i64, text, color, scale, false);
    text_size(text, scale)
}

/// Like [`draw_text`], rotated 90° counter-clockwise (reading bottom to top) with the start of the text at the
/// bottom-left corner `(x, y)`; the text occupies `x .. x + height` and `y - width .. y`.
pub fn draw_text_vertical(
    img: &mut RgbImage,
    x: i32,
    y: i32,
    text: &str,
    color: [u8; 3],
    scale: u32,
) {
    draw(img, x as i64, y as i64, text, color, scale, true);
}

/// Size `(width, height)` in pixels that [`draw_text`] covers (the widest line, and all lines).
pub fn text_size(text: &str, scale: u32) -> (u32, u32) {
    let s = scale.max(1);
    let lines = text.split('\n');
    let (mut w, mut n) = (0u32, 0u32);
    for line in lines {
        let chars = line.chars().count() as u32;
        if chars > 0 {
            w = w.max((chars * ADVANCE - (ADVANCE - GLYPH_WIDTH)) * s);
        }
        n += 1;
    }
    (w, ((n - 1) * LINE_HEIGHT + GLYPH_HEIGHT) * s)
}

fn draw(
    img: &mut RgbImage,
    x: i64,
    y: i64,
    text: &str,
    color: [u8; 3],
    scale: u32,
    vertical: bool,
) {
    let s = scale.max(1) as i64;
    for (line_no, line) in text.split('\n').enumerate() {
        for (k, c) in line.chars().enumerate() {
            let bits = glyph(c);
            // Glyph origin along the text direction (`along`) and across it (`across`).
            let along = k as i64 * ADVANCE as i64 * s;
            let across = line_no as i64 * LINE_HEIGHT as i64 * s;
            for (gy, row) in bits.iter().enumerate() {
                for gx in 0..GLYPH_WIDTH as i64 {
                    if row & (1 << (GLYPH_WIDTH as i64 - 1 - gx)) == 0 {
                        continue;
                    }
                    for dy in 0..s {
                        for dx in 0..s {
                            let u = along + gx * s + dx;
                            let v = across + gy as i64 * s + dy;
                            if vertical {
                                put(img, x + v, y - 1 - u, color);
                            } else {
                                put(img, x + u, y + v, color);
                            }
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draw_text_changes_pixels_and_clips() {
        let mut img = RgbImage::new(120, 30);
        let (w, h) = draw_text(&mut img, 2, 2, "INPUT 12.5%", [255, 255, 255], 1);
        assert_eq!((w, h), (11 * 6 - 1, 7));
        let lit = img.pixels().filter(|p| p.0 != [0, 0, 0]).count();
        assert!(lit > 40, "{lit}");
        // Everything drawn lies inside the reported box.
        for (x, y, p) in img.enumerate_pixels() {
            if p.0 != [0, 0, 0] {
                assert!((2..2 + w).contains(&x) && (2..2 + h).contains(&y));
            }
        }
        // Lowercase maps to uppercase.
        let mut a = RgbImage::new(40, 10);
        let mut b = RgbImage::new(40, 10);
        draw_text(&mut a, 0, 0, "frame", [9, 9, 9], 1);
        draw_text(&mut b, 0, 0, "FRAME", [9, 9, 9], 1);
        assert_eq!(a.as_raw(), b.as_raw());
        // Partly or entirely outside the image, scaled, vertical, unknown characters: no panic.
        draw_text(&mut img, -10, -3, "OUTPUT", [200, 0, 0], 3);
        draw_text(&mut img, i32::MAX, i32::MIN, "X", [200, 0, 0], 2);
        draw_text_vertical(&mut img, 0, 29, "STRETCH é", [0, 200, 0], 1);
        assert_eq!(text_size("AB\nC", 2), ((2 * 6 - 1) * 2, (9 + 7) * 2));
        assert_eq!(text_size("", 1), (0, 7));
    }

    #[test]
    fn glyphs_are_unique() {
        for (i, (c, g)) in GLYPHS.iter().enumerate() {
            for (d, h) in &GLYPHS[i + 1..] {
                assert!(c != d && (g != h || *c == ' '), "{c} {d}");
            }
        }
        for c in "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ .,:%-+=()/_#".chars() {
            assert!(GLYPHS.iter().any(|(g, _)| *g == c), "{c}");
        }
    }
}

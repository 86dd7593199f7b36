//! A 5×7 bitmap font for the scale bar's numbers: digits, `.`, `-`, `+`, `e`, `%`.
//!
//! Drawn by hand for this crate so that no system font (and no fontconfig) is needed.

/// Glyph rows, top to bottom; bit 4 is the leftmost pixel.
fn glyph(c: char) -> Option<[u8; 7]> {
    Some(match c {
        '0' => [
            0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110,
        ],
        '1' => [
            0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110,
        ],
        '2' => [
            0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111,
        ],
        '3' => [
            0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110,
        ],
        '4' => [
            0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010,
        ],
        '5' => [
            0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110,
        ],
        '6' => [
            0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110,
        ],
        '7' => [
            0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000,
        ],
        '8' => [
            0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110,
        ],
        '9' => [
            0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100,
        ],
        '.' => [0, 0, 0, 0, 0, 0b01100, 0b01100],
        '-' => [0, 0, 0, 0b11111, 0, 0, 0],
        '+' => [0, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0],
        'e' => [0, 0, 0b01110, 0b10001, 0b11111, 0b10000, 0b01110],
        '%' => [
            0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011,
        ],
        ' ' => [0; 7],
        _ => return None,
    })
}

/// Width of one character cell (glyph plus one column of spacing) at scale 1.
pub const CELL_WIDTH: usize = 6;
/// Height of a glyph at scale 1.
pub const GLYPH_HEIGHT: usize = 7;

/// Width in pixels of `text` drawn at `scale` (without the trailing spacing column).
#[must_use]
pub fn text_width(text: &str, scale: usize) -> usize {
    (text.chars().count() * CELL_WIDTH).saturating_sub(1) * scale
}

/// Draws `text` with its top-left corner at `(x0, y0)` into an RGB8 buffer of `width` pixels
/// per row; pixels outside the buffer and characters without a glyph are skipped.
pub fn draw_text(
    buf: &mut [[u8; 3]],
    width: usize,
    x0: usize,
    y0: usize,
    text: &str,
    scale: usize,
    colour: [u8; 3],
) {
    let height = buf.len() / width.max(1);
    for (k, c) in text.chars().enumerate() {
        let Some(rows) = glyph(c) else { continue };
        for (r, bits) in rows.iter().enumerate() {
            for col in 0..5 {
                if bits & (0b10000 >> col) == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let x = x0 + (k * CELL_WIDTH + col) * scale + dx;
                        let y = y0 + r * scale + dy;
                        if x < width && y < height {
                            buf[y * width + x] = colour;
                        }
                    }
                }
            }
        }
    }
}

/// A number with 3 significant digits, as short as possible: `0`, `0.0123`, `4.56`, `1.2e-5`.
#[must_use]
pub fn format_number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v.is_finite() {
            "0".into()
        } else {
            "-".into()
        };
    }
    let a = v.abs();
    if (1e-3..1e4).contains(&a) {
        let digits_before = a.log10().floor() as i32 + 1;
        let decimals = (3 - digits_before).max(0) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        let s = format!("{v:.2e}");
        // "1.20e-5" -> "1.2e-5"
        match s.split_once('e') {
            Some((m, e)) => {
                let m = if m.contains('.') {
                    m.trim_end_matches('0').trim_end_matches('.')
                } else {
                    m
                };
                format!("{m}e{e}")
            }
            None => s,
        }
    }
}

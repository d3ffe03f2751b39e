//! Text in the overlay: the 8 x 8 bitmap glyphs of the `font8x8` crate (basic latin), laid out
//! on a fixed grid of `8 * scale` pixels per character.

/// Side of a glyph cell in font pixels (each drawn as `scale x scale` screen pixels).
pub const GLYPH: i32 = 8;
/// Line pitch in font pixels: the glyph and two pixels of leading.
pub const LINE: i32 = 10;

/// The glyph of `c` as two words: rows 0-3 in the first, rows 4-7 in the second, one byte per row,
/// bit `c` of a row byte the pixel in column `c` from the left (font8x8's convention). Characters
/// outside basic latin (U+0000-U+007F) draw as `?`.
pub fn glyph_bits(c: char) -> [u32; 2] {
    let rows = font8x8::legacy::BASIC_LEGACY
        .get(c as usize)
        .copied()
        .unwrap_or(font8x8::legacy::BASIC_LEGACY[usize::from(b'?')]);
    [
        u32::from_le_bytes([rows[0], rows[1], rows[2], rows[3]]),
        u32::from_le_bytes([rows[4], rows[5], rows[6], rows[7]]),
    ]
}

/// Whether font pixel (`col`, `row`) (0..8 each, row 0 at the top) of a glyph is set.
pub fn glyph_pixel(bits: [u32; 2], col: u32, row: u32) -> bool {
    if col >= 8 || row >= 8 {
        return false;
    }
    let bit = row * 8 + col;
    (bits[(bit / 32) as usize] >> (bit % 32)) & 1 == 1
}

/// Width in screen pixels of `s` drawn at `scale` (every character is one cell wide).
pub fn text_width(s: &str, scale: u32) -> i32 {
    s.chars().count() as i32 * GLYPH * scale as i32
}

/// Height in screen pixels of `lines` lines at `scale`: the last line without its leading.
pub fn block_height(lines: usize, scale: u32) -> i32 {
    if lines == 0 {
        return 0;
    }
    ((lines as i32 - 1) * LINE + GLYPH) * scale as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glyph_a_is_font8x8_basic_a() {
        // U+0041 in dhepper's public-domain font8x8_basic.h, one byte per row, bit 0 leftmost:
        // { 0x0C, 0x1E, 0x33, 0x33, 0x3F, 0x33, 0x33, 0x00 }.
        let want: [u8; 8] = [0x0C, 0x1E, 0x33, 0x33, 0x3F, 0x33, 0x33, 0x00];
        let bits = glyph_bits('A');
        for (row, byte) in want.iter().enumerate() {
            for col in 0..8u32 {
                assert_eq!(
                    glyph_pixel(bits, col, row as u32),
                    (byte >> col) & 1 == 1,
                    "A ({col}, {row})"
                );
            }
        }
        // Row 0 is 0x0C: columns 2 and 3 only.
        let row0: Vec<u32> = (0..8).filter(|&c| glyph_pixel(bits, c, 0)).collect();
        assert_eq!(row0, vec![2, 3]);
        assert_eq!(glyph_bits(' '), [0, 0]);
        assert_eq!(glyph_bits('é'), glyph_bits('?'));
        assert!(!glyph_pixel(bits, 8, 0) && !glyph_pixel(bits, 0, 8));
    }

    #[test]
    fn widths_and_heights_follow_the_grid() {
        assert_eq!(text_width("", 2), 0);
        assert_eq!(text_width("fps", 1), 24);
        // Characters, not bytes: "µs" is two cells.
        assert_eq!(text_width("µs", 2), 32);
        assert_eq!(block_height(0, 2), 0);
        assert_eq!(block_height(1, 1), 8);
        // Three lines at scale 2: two pitches of 20 and one glyph of 16.
        assert_eq!(block_height(3, 2), 56);
    }
}

//! Shelf packing of axis-aligned rectangles on the texel grid: tallest first (then widest,
//! then by index, so the layout is a pure function of the sizes), left to right along a
//! shelf whose height is its first rectangle's, a new shelf below when a row is full.

/// Places rectangles `sizes[i] = (w, h)` (texels) in a `width × height` grid: each one's
/// top-left corner, or `None` when they do not all fit.
pub(crate) fn shelf_pack(sizes: &[(u32, u32)], width: u32, height: u32) -> Option<Vec<(u32, u32)>> {
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    order.sort_by(|&a, &b| {
        let (wa, ha) = sizes[a];
        let (wb, hb) = sizes[b];
        hb.cmp(&ha).then(wb.cmp(&wa)).then(a.cmp(&b))
    });
    let mut at = vec![(0u32, 0u32); sizes.len()];
    let (mut x, mut y, mut shelf) = (0u64, 0u64, 0u64);
    let (width, height) = (u64::from(width), u64::from(height));
    for i in order {
        let (w, h) = (u64::from(sizes[i].0), u64::from(sizes[i].1));
        if w > width {
            return None;
        }
        if x + w > width {
            y += shelf;
            x = 0;
            shelf = 0;
        }
        if y + h > height {
            return None;
        }
        at[i] = (x as u32, y as u32);
        x += w;
        shelf = shelf.max(h);
    }
    Some(at)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shelves_fill_rows_tallest_first_and_refuse_what_does_not_fit() {
        let at = shelf_pack(&[(2, 1), (2, 3), (2, 2), (4, 1)], 6, 5).unwrap();
        // Sorted: (2,3) (2,2) on the first shelf; (4,1) (wider than (2,1)) does not fit
        // beside them (2 + 2 + 4 > 6) and opens the second shelf at y = 3, (2,1) after it.
        assert_eq!(at, vec![(4, 3), (0, 0), (2, 0), (0, 3)]);
        assert!(shelf_pack(&[(2, 3), (2, 3), (2, 3), (2, 3)], 6, 5).is_none());
        assert!(shelf_pack(&[(7, 1)], 6, 5).is_none());
    }
}

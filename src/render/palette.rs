//! One colour table for every frame of an animation. The drawings use a handful of flat colours
//! (ground, asphalt, marks, car fills) plus the blends of anti-aliased edges, so the table holds
//! the 256 most frequent colours over all frames exactly and every rarer colour takes its
//! nearest entry. One table keeps a colour the same in every frame (no flicker of the road
//! between frames, as separate per-frame tables can give) and the file small.

use std::collections::HashMap;

/// Most colours a GIF colour table holds.
const MAX_COLORS: usize = 256;

/// Counts the colours of RGB frames, one frame at a time.
#[derive(Debug, Default)]
pub(super) struct ColorCounts(HashMap<[u8; 3], u64>);

impl ColorCounts {
    pub(super) fn add(&mut self, rgb: &[u8]) {
        for px in rgb.chunks_exact(3) {
            *self.0.entry([px[0], px[1], px[2]]).or_default() += 1;
        }
    }
}

/// The colour table and the index of every colour met so far.
#[derive(Debug)]
pub(super) struct Palette {
    colors: Vec<[u8; 3]>,
    index: HashMap<[u8; 3], u8>,
}

impl Palette {
    /// The `MAX_COLORS` most frequent colours (ties broken by colour, so the table does not
    /// depend on the hash map's order).
    pub(super) fn from_counts(counts: ColorCounts) -> Self {
        let mut ranked: Vec<([u8; 3], u64)> = counts.0.into_iter().collect();
        ranked.sort_unstable_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        ranked.truncate(MAX_COLORS);
        let colors: Vec<[u8; 3]> = ranked.into_iter().map(|(c, _)| c).collect();
        let index = colors
            .iter()
            .enumerate()
            .map(|(k, &c)| (c, k as u8))
            .collect();
        Self { colors, index }
    }

    /// The table as `r, g, b, r, g, b, ...` (at least one entry).
    pub(super) fn rgb(&self) -> Vec<u8> {
        if self.colors.is_empty() {
            return vec![0; 3];
        }
        self.colors.iter().flatten().copied().collect()
    }

    /// The table index of every pixel of an RGB frame.
    pub(super) fn indices(&mut self, rgb: &[u8]) -> Vec<u8> {
        rgb.chunks_exact(3)
            .map(|px| self.index_of([px[0], px[1], px[2]]))
            .collect()
    }

    fn index_of(&mut self, color: [u8; 3]) -> u8 {
        if let Some(&k) = self.index.get(&color) {
            return k;
        }
        let distance = |c: &[u8; 3]| -> u32 {
            (0..3)
                .map(|k| (i32::from(c[k]) - i32::from(color[k])).pow(2) as u32)
                .sum()
        };
        let nearest = (0..self.colors.len())
            .min_by_key(|&k| distance(&self.colors[k]))
            .unwrap_or(0) as u8;
        self.index.insert(color, nearest);
        nearest
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frequent_colours_are_exact_and_rare_ones_take_the_nearest() {
        let mut counts = ColorCounts::default();
        // 300 distinct colours: (k, 0, 0) appears k + 1 times.
        let mut frame = Vec::new();
        for k in 0..300u32 {
            for _ in 0..=k {
                frame.extend([(k % 256) as u8, (k / 256) as u8 * 100, 0]);
            }
        }
        counts.add(&frame);
        let mut palette = Palette::from_counts(counts);
        assert_eq!(palette.rgb().len(), 3 * MAX_COLORS);
        // The most frequent colour is first; the rarest ones were left out.
        assert_eq!(&palette.rgb()[..3], &[43, 100, 0]);
        let [kept] = palette.indices(&[43, 100, 0])[..] else {
            panic!()
        };
        assert_eq!(palette.colors[kept as usize], [43, 100, 0]);
        let [near] = palette.indices(&[0, 1, 0])[..] else {
            panic!()
        };
        // (0, 0, 0) is among the rarest and left out; its nearest kept colour is (44, 0, 0).
        assert_eq!(palette.colors[near as usize], [44, 0, 0]);
    }
}

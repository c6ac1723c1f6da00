//! A grid cache of [`Map::point_location`], for the simulator's off-road test at millions of
//! boxes per second.
//!
//! The exact query is evaluated once at every grid corner. A point in a cell whose four
//! corners agree takes that answer; a point in a cell whose corners disagree (a cell that a
//! lane edge or road end crosses) falls back to the exact query, as does a point outside the
//! grid. So the answer equals the exact one except where a feature narrower than a cell fits
//! entirely between corners (the last centimetres of a tapering lane; on a lanelet map, the
//! tip of a gap between two shoulder strips), which the default 0.25 m cell makes negligible.

use super::lanes::Map;
use super::query::{BEYOND_END_RANGE, BoxOnRoad, PointLocation, classify_outline};
use crate::geometry::OrientedBox;

const ON: u8 = 0;
const BEYOND: u8 = 1;
const OFF: u8 = 2;
const MIXED: u8 = 3;

/// Default cell size (m).
pub const RASTER_CELL: f64 = 0.25;

#[derive(Debug, Clone)]
pub struct RoadRaster {
    origin: [f64; 2],
    cell: f64,
    nx: usize,
    ny: usize,
    /// Per cell: ON, BEYOND or OFF when its corners agree, else MIXED.
    cells: Vec<u8>,
    /// Per cell: Chebyshev distance (in cells) to the nearest cell that is not ON; a box
    /// whose bounding circle fits inside that clearance is on the road without testing its
    /// outline.
    clearance: Vec<u16>,
}

fn code(l: PointLocation) -> u8 {
    match l {
        PointLocation::OnRoad => ON,
        PointLocation::BeyondRoadEnd => BEYOND,
        PointLocation::OffRoad => OFF,
    }
}

impl RoadRaster {
    /// Covers the map's bounds plus the range in which points still count as past a road end.
    pub fn new(map: &Map, cell: f64) -> Self {
        let (min, max) = map.bounds();
        let margin = BEYOND_END_RANGE.min(10.0);
        let origin = [min[0] - margin, min[1] - margin];
        let nx = ((max[0] - min[0] + 2.0 * margin) / cell).ceil().max(1.0) as usize;
        let ny = ((max[1] - min[1] + 2.0 * margin) / cell).ceil().max(1.0) as usize;
        let corner = |i: usize, j: usize| {
            code(map.point_location([origin[0] + i as f64 * cell, origin[1] + j as f64 * cell]))
        };
        let mut corners = vec![OFF; (nx + 1) * (ny + 1)];
        for j in 0..=ny {
            for i in 0..=nx {
                corners[j * (nx + 1) + i] = corner(i, j);
            }
        }
        let mut cells = vec![MIXED; nx * ny];
        for j in 0..ny {
            for i in 0..nx {
                let at = |di: usize, dj: usize| corners[(j + dj) * (nx + 1) + i + di];
                let c = at(0, 0);
                if at(1, 0) == c && at(0, 1) == c && at(1, 1) == c {
                    cells[j * nx + i] = c;
                }
            }
        }
        let clearance = chebyshev_clearance(&cells, nx, ny);
        Self {
            origin,
            cell,
            nx,
            ny,
            cells,
            clearance,
        }
    }

    /// Same answer as `map.point_location(p)` (see the module note), fast.
    pub fn point_location(&self, map: &Map, p: [f64; 2]) -> PointLocation {
        let fx = (p[0] - self.origin[0]) / self.cell;
        let fy = (p[1] - self.origin[1]) / self.cell;
        if fx >= 0.0 && fy >= 0.0 && (fx as usize) < self.nx && (fy as usize) < self.ny {
            match self.cells[fy as usize * self.nx + fx as usize] {
                ON => return PointLocation::OnRoad,
                BEYOND => return PointLocation::BeyondRoadEnd,
                OFF => return PointLocation::OffRoad,
                _ => {}
            }
        }
        map.point_location(p)
    }

    /// Same answer as `map.box_on_road(b)`, fast.
    pub fn box_on_road(&self, map: &Map, b: &OrientedBox) -> BoxOnRoad {
        // Quick accept: every cell within (k - 1) cells (Chebyshev) of the centre's cell is ON,
        // so a disc of radius (k - 1) * cell around the centre lies on the road.
        let fx = (b.center[0] - self.origin[0]) / self.cell;
        let fy = (b.center[1] - self.origin[1]) / self.cell;
        if fx >= 0.0 && fy >= 0.0 && (fx as usize) < self.nx && (fy as usize) < self.ny {
            let k = self.clearance[fy as usize * self.nx + fx as usize] as f64;
            if (k - 1.0) * self.cell >= b.bounding_radius() {
                return BoxOnRoad::OnRoad;
            }
        }
        classify_outline(b, |p| self.point_location(map, p))
    }
}

/// Multi-source breadth-first search from every cell that is not ON (and from outside the
/// grid) over 8-neighbours, which yields the Chebyshev distance.
fn chebyshev_clearance(cells: &[u8], nx: usize, ny: usize) -> Vec<u16> {
    let mut dist = vec![u16::MAX; nx * ny];
    let mut queue = std::collections::VecDeque::new();
    for j in 0..ny {
        for i in 0..nx {
            let border = i == 0 || j == 0 || i + 1 == nx || j + 1 == ny;
            if cells[j * nx + i] != ON || border {
                dist[j * nx + i] = 0;
                queue.push_back((i, j));
            }
        }
    }
    while let Some((i, j)) = queue.pop_front() {
        let d = dist[j * nx + i].saturating_add(1);
        for (di, dj) in [
            (-1i64, -1i64),
            (0, -1),
            (1, -1),
            (-1, 0),
            (1, 0),
            (-1, 1),
            (0, 1),
            (1, 1),
        ] {
            let (a, b) = (i as i64 + di, j as i64 + dj);
            if a < 0 || b < 0 || a >= nx as i64 || b >= ny as i64 {
                continue;
            }
            let at = b as usize * nx + a as usize;
            if dist[at] > d {
                dist[at] = d;
                queue.push_back((a as usize, b as usize));
            }
        }
    }
    dist
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::test_maps::a9;

    #[test]
    fn raster_agrees_with_the_exact_query_on_a_dense_sweep() {
        let map = a9();
        let raster = RoadRaster::new(&map, RASTER_CELL);
        let (min, max) = map.bounds();
        let (mut n, mut on) = (0, 0);
        // An irregular sweep (0.37 m x 0.53 m) so points do not sit on grid corners.
        let mut y = min[1] - 12.0;
        while y < max[1] + 12.0 {
            let mut x = min[0] - 12.0;
            while x < max[0] + 12.0 {
                let exact = map.point_location([x, y]);
                assert_eq!(raster.point_location(&map, [x, y]), exact, "at ({x}, {y})");
                on += usize::from(exact == PointLocation::OnRoad);
                n += 1;
                x += 0.37;
            }
            y += 0.53;
        }
        assert!(on > 10_000 && on < n, "{on} of {n} points on the road");
    }

    #[test]
    fn raster_box_test_agrees_with_the_exact_one() {
        let map = a9();
        let raster = RoadRaster::new(&map, RASTER_CELL);
        let (min, max) = map.bounds();
        let (mut n, mut on) = (0, 0);
        for i in 0..3000 {
            let f = i as f64;
            let center = [
                min[0] + (max[0] - min[0]) * ((f * 0.618_034) % 1.0),
                min[1] - 5.0 + (max[1] - min[1] + 10.0) * ((f * 0.414_214) % 1.0),
            ];
            let heading = 1.6 + 0.2 * (f * 0.7).sin();
            let length = if i % 3 == 0 { 16.0 } else { 4.5 };
            let b = OrientedBox::new(center, heading, length, 2.0);
            let exact = map.box_on_road(&b);
            assert_eq!(raster.box_on_road(&map, &b), exact, "{b:?}");
            n += 1;
            on += usize::from(exact == BoxOnRoad::OnRoad);
        }
        assert!(on > 300 && on < n - 300, "{on} of {n} boxes on the road");
    }
}

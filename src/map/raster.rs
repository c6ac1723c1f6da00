//! A grid cache of [`Map::point_location`], for the simulator's off-road test at millions of
//! boxes per second.
//!
//! The exact query is evaluated once at every grid corner. A point in a cell whose four
//! corners agree takes that answer; a point in a cell whose corners disagree (a cell that a
//! lane edge or road end crosses) falls back to the exact query, as does a point outside the
//! grid. So the answer equals the exact one except where a feature narrower than a cell fits
//! entirely between corners (the last centimetres of a tapering lane; on a lanelet map, the
//! tip of a gap between two shoulder strips), which the default 0.25 m cell makes negligible.
//!
//! The grid is filled lazily in square tiles, each on its first query: a rollout touches the
//! tiles along its vehicles' paths, a small part of a generated map's bounding box (a 900 m
//! curve spans millions of cells, and filling them all cost more than the rollouts on it).

use std::sync::OnceLock;

use super::lanes::Map;
use super::query::{BEYOND_END_RANGE, BoxOnRoad, PointLocation, classify_outline};
use crate::geometry::OrientedBox;

const ON: u8 = 0;
const BEYOND: u8 = 1;
const OFF: u8 = 2;
const MIXED: u8 = 3;

/// Default cell size (m).
pub const RASTER_CELL: f64 = 0.25;

/// Cells per tile side: 16 m at the default cell, a few exact queries per metre of road
/// driven, and clearances up to 32 cells (8 m) inside a tile.
const TILE: usize = 64;

#[derive(Debug)]
pub struct RoadRaster {
    origin: [f64; 2],
    cell: f64,
    nx: usize,
    ny: usize,
    /// Tiles per row.
    tiles_x: usize,
    /// Row-major, each filled on first use.
    tiles: Vec<OnceLock<Tile>>,
}

/// One filled tile.
#[derive(Debug)]
struct Tile {
    /// Cells per row of this tile (the last column and row of tiles may be narrower).
    width: usize,
    /// Per cell: ON, BEYOND or OFF when its corners agree, else MIXED.
    cells: Vec<u8>,
    /// Per cell: a lower bound on the Chebyshev distance (in cells) to the nearest cell that is
    /// not ON (cells outside the tile count as not ON); a box whose bounding circle fits inside
    /// it is on the road without testing its outline.
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
    /// Nothing is queried yet.
    pub fn new(map: &Map, cell: f64) -> Self {
        let (min, max) = map.bounds();
        let margin = BEYOND_END_RANGE.min(10.0);
        let origin = [min[0] - margin, min[1] - margin];
        let nx = ((max[0] - min[0] + 2.0 * margin) / cell).ceil().max(1.0) as usize;
        let ny = ((max[1] - min[1] + 2.0 * margin) / cell).ceil().max(1.0) as usize;
        let (tiles_x, tiles_y) = (nx.div_ceil(TILE), ny.div_ceil(TILE));
        Self {
            origin,
            cell,
            nx,
            ny,
            tiles_x,
            tiles: (0..tiles_x * tiles_y).map(|_| OnceLock::new()).collect(),
        }
    }

    /// Tiles filled so far.
    pub fn filled_tiles(&self) -> usize {
        self.tiles.iter().filter(|t| t.get().is_some()).count()
    }

    /// The cell holding `p` as (tile, index within the tile), filling its tile; `None` outside
    /// the grid.
    fn cell_of(&self, map: &Map, p: [f64; 2]) -> Option<(&Tile, usize)> {
        let fx = (p[0] - self.origin[0]) / self.cell;
        let fy = (p[1] - self.origin[1]) / self.cell;
        if !(fx >= 0.0 && fy >= 0.0 && (fx as usize) < self.nx && (fy as usize) < self.ny) {
            return None;
        }
        let (i, j) = (fx as usize, fy as usize);
        let (ti, tj) = (i / TILE, j / TILE);
        let tile = self.tiles[tj * self.tiles_x + ti].get_or_init(|| self.fill(map, ti, tj));
        Some((tile, (j % TILE) * tile.width + i % TILE))
    }

    /// Evaluates the exact query at the corners of tile (`ti`, `tj`).
    fn fill(&self, map: &Map, ti: usize, tj: usize) -> Tile {
        let (i0, j0) = (ti * TILE, tj * TILE);
        let width = TILE.min(self.nx - i0);
        let height = TILE.min(self.ny - j0);
        let mut corners = vec![OFF; (width + 1) * (height + 1)];
        for j in 0..=height {
            for i in 0..=width {
                corners[j * (width + 1) + i] = code(map.point_location([
                    self.origin[0] + (i0 + i) as f64 * self.cell,
                    self.origin[1] + (j0 + j) as f64 * self.cell,
                ]));
            }
        }
        let mut cells = vec![MIXED; width * height];
        for j in 0..height {
            for i in 0..width {
                let at = |di: usize, dj: usize| corners[(j + dj) * (width + 1) + i + di];
                let c = at(0, 0);
                if at(1, 0) == c && at(0, 1) == c && at(1, 1) == c {
                    cells[j * width + i] = c;
                }
            }
        }
        let clearance = chebyshev_clearance(&cells, width, height);
        Tile {
            width,
            cells,
            clearance,
        }
    }

    /// Same answer as `map.point_location(p)` (see the module note), fast.
    pub fn point_location(&self, map: &Map, p: [f64; 2]) -> PointLocation {
        if let Some((tile, k)) = self.cell_of(map, p) {
            match tile.cells[k] {
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
        if let Some((tile, k)) = self.cell_of(map, b.center) {
            let k = tile.clearance[k] as f64;
            if (k - 1.0) * self.cell >= b.bounding_radius() {
                return BoxOnRoad::OnRoad;
            }
        }
        classify_outline(b, |p| self.point_location(map, p))
    }
}

/// Multi-source breadth-first search from every cell that is not ON and from the tile's edge
/// cells (what lies beyond is not known here) over 8-neighbours, which yields the Chebyshev
/// distance within the tile, a lower bound of the distance over the whole grid.
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
    fn only_the_tiles_queried_are_filled() {
        let map = a9();
        let raster = RoadRaster::new(&map, RASTER_CELL);
        assert_eq!(raster.filled_tiles(), 0);
        let (min, max) = map.bounds();
        let centre = [(min[0] + max[0]) / 2.0, (min[1] + max[1]) / 2.0];
        let exact = map.point_location(centre);
        assert_eq!(raster.point_location(&map, centre), exact);
        assert_eq!(raster.filled_tiles(), 1);
        assert_eq!(raster.point_location(&map, centre), exact);
        assert_eq!(raster.filled_tiles(), 1);
        assert!(raster.tiles.len() > 50, "{} tiles", raster.tiles.len());
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

//! [`SkyGrid`]: the sky on a refined grid of pixel nodes, read row by row (the fast path).

use super::*;

/// Relative interpolation tolerance of the PSNS presets' sky grid and of `psns bench sky`:
/// estimated error at most this fraction of S0 (a tenth of the shot noise of a full 10 500 e⁻
/// well is 1e-3). The camera's frames take theirs from its full well
/// (`RawPipeline::grid_tolerance`).
pub const GRID_TOLERANCE: f64 = 2.5e-4;

/// Sensor-frame Stokes planes from a [`SkyGrid`] of tolerance `tol` (`step` = 1: the exact
/// render).
pub fn render_stokes_grid(
    sky: &Sky,
    cam: &Camera,
    opts: StokesOptions,
    step: usize,
    tol: f64,
) -> (StokesImage, usize) {
    if step <= 1 {
        return render_stokes(sky, cam, opts);
    }
    let g = SkyGrid::new(sky, cam, opts, step, tol);
    (g.to_image(), g.sun_pixels())
}

/// A refined cell: nodes every `step` pixels (the last at the cell's far edge), and per sub-cell
/// whether it is evaluated exactly at every pixel.
#[derive(Clone, Debug)]
pub(super) struct SubGrid {
    /// The coarse cell's column index (its row is the band holding it in `SkyGrid::band_subs`).
    cell: usize,
    /// Node spacing (the last interval of each axis may be shorter).
    step: usize,
    cols: Vec<usize>,
    rows: Vec<usize>,
    nodes: Vec<[f32; 3]>,
    exact: Vec<bool>,
    /// Cloud opacity at the nodes (empty without clouds).
    alpha: Vec<f32>,
}

impl SubGrid {
    /// Row `r` of this refined cell in a band whose first row is `r0`, `sky_cols` the coarse
    /// node columns: the sub-row `jj` holding it, the weight `fy` between sub-rows `jj` and
    /// `jj + 1`, and each sub-cell as (`ii`, first column, next node's column, end), the last
    /// reaching the cell's end (past the image's last node in the last coarse cell).
    fn row(
        &self,
        r: usize,
        r0: usize,
        sky_cols: &[usize],
    ) -> (
        usize,
        f32,
        impl Iterator<Item = (usize, usize, usize, usize)> + '_,
    ) {
        let (gw, i) = (sky_cols.len(), self.cell);
        let c_end = if i + 2 == gw {
            sky_cols[i + 1] + 1
        } else {
            sky_cols[i + 1]
        };
        let (sw, sh) = (self.cols.len(), self.rows.len());
        let jj = ((r - r0) / self.step).min(sh - 2);
        let (sr0, sr1) = (self.rows[jj], self.rows[jj + 1]);
        let fy = (r - sr0) as f32 / (sr1 - sr0) as f32;
        let cells = (0..sw - 1).map(move |ii| {
            let (a0, a1) = (self.cols[ii], self.cols[ii + 1]);
            (ii, a0, a1, if ii + 2 == sw { c_end } else { a1 })
        });
        (jj, fy, cells)
    }
}

/// The sky on a coarse grid of pixel nodes, refined where bilinear interpolation would be off by
/// more than `tol` · S0 and evaluated exactly where a cell straddles the horizon.
///
/// Nodes sit every `step` pixels (and on the last row and column). The interpolation error of a
/// cell is estimated from the second differences of the node values at its corners,
/// (|Δ²ₓ| + |Δ²ᵧ|)/8 summed over S0, S1, S2 (the bound for bilinear interpolation of a function
/// with those second derivatives). A cell above tolerance gets sub-nodes every `step`/4 pixels
/// and the same test per sub-cell; sub-cells still above it, and all sub-cells with a corner on
/// the ground, are evaluated at every pixel. In a pinhole camera the horizon is a straight line,
/// so a cell whose four corners see sky sees only sky. The solar disc is added exactly, as in
/// [`render_stokes`]. Rows are produced on demand ([`StokesRows`]); the measured cost and error
/// are in `docs/performance.md`.
pub struct SkyGrid<'a> {
    /// Node spacing (the last interval of each axis may be shorter).
    step: usize,
    sky: &'a Sky,
    cam: &'a Camera,
    width: usize,
    height: usize,
    pub(super) cols: Vec<usize>,
    pub(super) rows: Vec<usize>,
    pub(super) nodes: Vec<[f32; 3]>,
    /// The refined cells, in row-major order of the coarse cells.
    subs: Vec<SubGrid>,
    /// The refined cells of band j (coarse cell row j) are `subs[band_subs[j]..band_subs[j + 1]]`.
    band_subs: Vec<usize>,
    /// Solar disc additions to S0: (pixel index, radiance), sorted by index.
    pub(super) disc: Vec<(usize, f32)>,
    exact_pixels: usize,
    /// With clouds in front of the sky: the nodes sample the sky without them
    /// ([`Sky::without_direct_clouds`]) and the clouds' opacity, interpolated apart and laid
    /// over the interpolated sky (`alpha` per node, `cloudy` per band of cells); the exact
    /// pixels see them as `sky` does.
    alpha: Vec<f32>,
    /// Cells refined for the clouds alone (opacity at their nodes, no sky), by band as `subs`.
    alpha_subs: Vec<SubGrid>,
    band_alpha: Vec<usize>,
    cloudy: Vec<bool>,
    cloud_radiance: f32,
}

/// Node positions 0, step, 2 step, … and always n − 1.
pub(super) fn grid_nodes(start: usize, end: usize, step: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (start..=end).step_by(step.max(1)).collect();
    if *v.last().unwrap() != end {
        v.push(end);
    }
    v
}

/// Per node, the interpolation-error estimate (|Δ²ₓ| + |Δ²ᵧ|)/8 summed over the planes;
/// one-sided at the edges (the neighbour's second difference); infinite along an axis with fewer
/// than three nodes.
pub(super) fn curvature(nodes: &[[f32; 3]], gw: usize, gh: usize) -> Vec<f32> {
    let at = |i: usize, j: usize| nodes[j * gw + i];
    let d2 = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| -> f32 {
        (0..3).map(|k| (a[k] - 2.0 * b[k] + c[k]).abs()).sum()
    };
    let mut out = vec![0f32; gw * gh];
    out.par_chunks_mut(gw.max(1))
        .enumerate()
        .for_each(|(j, row)| {
            for (i, o) in row.iter_mut().enumerate() {
                // with fewer than three nodes along an axis the curvature is unknown: infinite, so
                // the cell is refined rather than trusted
                let dx = if gw < 3 {
                    f32::INFINITY
                } else {
                    let m = i.clamp(1, gw - 2);
                    d2(at(m - 1, j), at(m, j), at(m + 1, j))
                };
                let dy = if gh < 3 {
                    f32::INFINITY
                } else {
                    let m = j.clamp(1, gh - 2);
                    d2(at(i, m - 1), at(i, m), at(i, m + 1))
                };
                *o = (dx + dy) / 8.0;
            }
        });
    out
}

/// Whether the sky seen within `span` pixels of (col, row) is certainly free of the horizon and of
/// a fisheye's image-circle rim, judged by angle: the pixel's angular distance from either must
/// exceed the angle `span` pixels can cover there (√2 span times the larger of the radial and
/// tangential angle per pixel, with a factor 1.5 for its change across the cell). Only for
/// fisheyes: in a rectilinear camera the horizon is a straight line and a cell whose corners see
/// sky sees only sky.
pub(super) fn clear_of_edges(
    cam: &Camera,
    world: Option<&Surroundings>,
    col: usize,
    row: usize,
    span: usize,
) -> bool {
    let i = &cam.intrinsics;
    let Some(ray) = i.ray(col as f64, row as f64) else {
        return false;
    };
    let theta = ray.x.hypot(ray.y).atan2(ray.z);
    let p = i.projection;
    let per_px = 1.0 / (i.focal_px() * p.radial_scale(theta).min(p.tangential_scale(theta)));
    let margin = 1.5 * std::f64::consts::SQRT_2 * span as f64 * per_px;
    let d = (cam.enu_to_camera.transpose() * ray).normalize();
    let up = d.z.clamp(-1.0, 1.0).asin();
    std::f64::consts::FRAC_PI_2 - theta > margin
        && up > margin
        && world.is_none_or(|w| w.world().clear(d, margin, true))
}

/// Whether every pixel of the cell with corners (c0, r0), (c1, r1) lies outside a fisheye's
/// image circle, with a pixel to spare: no light arrives there, and its nodes (all dark, zero)
/// interpolate to the zero each pixel would give.
pub(super) fn beyond_rim(cam: &Camera, c0: usize, c1: usize, r0: usize, r1: usize) -> bool {
    let i = &cam.intrinsics;
    let Some(rim) = i.projection.rim_radius() else {
        return false;
    };
    let (pc, pr) = i.principal();
    // the cell's nearest point to the circle's centre
    let dx = pc.clamp(c0 as f64, c1 as f64) - pc;
    let dy = pr.clamp(r0 as f64, r1 as f64) - pr;
    dx.hypot(dy) > rim * i.focal_px() + 1.0
}

/// Whether the cloud opacity differs between the corners of cell (i, j) (no clouds: never).
fn alpha_varies(alpha: &[f32], gw: usize, i: usize, j: usize) -> bool {
    if alpha.is_empty() {
        return false;
    }
    let a = alpha[j * gw + i];
    [j * gw + i + 1, (j + 1) * gw + i, (j + 1) * gw + i + 1]
        .iter()
        .any(|&k| alpha[k] != a)
}

/// Whether the cell (i, j) of a node grid needs more than bilinear interpolation.
pub(super) fn cell_needs_more(
    nodes: &[[f32; 3]],
    valid: &[bool],
    curv: &[f32],
    gw: usize,
    i: usize,
    j: usize,
    tol: f32,
) -> bool {
    let k = [
        j * gw + i,
        j * gw + i + 1,
        (j + 1) * gw + i,
        (j + 1) * gw + i + 1,
    ];
    if !k.iter().all(|&k| valid[k]) {
        return true;
    }
    let s0min = k.iter().map(|&k| nodes[k][0]).fold(f32::MAX, f32::min);
    let err = k.iter().map(|&k| curv[k]).fold(0f32, f32::max);
    err.is_nan() || err > tol * s0min
}

impl<'a> SkyGrid<'a> {
    /// Evaluates the nodes and refines (see the type docs). `step` ≥ 2.
    pub fn new(sky: &'a Sky, cam: &'a Camera, opts: StokesOptions, step: usize, tol: f64) -> Self {
        let (w, h) = (cam.intrinsics.width, cam.intrinsics.height);
        let step = step.max(2);
        let (cols, rows) = (grid_nodes(0, w - 1, step), grid_nodes(0, h - 1, step));
        let (gw, gh) = (cols.len(), rows.len());
        let sub_step = (step / 4).max(1);
        // fisheyes: a node near the horizon or the image-circle rim counts as invalid, so the
        // cells around it are refined and evaluated exactly (`clear_of_edges`)
        // with a world, every projection: its edges are no straight lines
        let world = sky.surroundings();
        let clear_sky = sky.without_direct_clouds();
        let split = clear_sky.is_some();
        let node_sky: &Sky = clear_sky.as_ref().unwrap_or(sky);
        let fisheye =
            cam.intrinsics.projection != crate::camera::Projection::Rectilinear || world.is_some();
        // the nodes (cols[k], r) of one row: Stokes and whether to trust them
        let eval_row = |r: usize, cols: &[usize], span: usize| -> Vec<([f32; 3], bool, f32)> {
            let mut px = vec![PixelSky::default(); cols.len()];
            pixel_sky_cols(node_sky, cam, r, cols, &mut px);
            px.iter()
                .zip(cols)
                .map(|(p, &c)| {
                    let [a, b, d] = p.stokes();
                    let ok = p.valid && (!fisheye || clear_of_edges(cam, world, c, r, span));
                    let alpha = match (split, world) {
                        (true, Some(w)) => cam
                            .pixel_direction(c as f64, r as f64)
                            .map_or(0.0, |d| w.direct_opacity(d) as f32),
                        _ => 0.0,
                    };
                    ([a as f32, b as f32, d as f32], ok, alpha)
                })
                .collect()
        };
        // the solar disc (sequential) beside the nodes and their refinement
        let ((nodes, band_subs, subs, exact_pixels, alpha, (band_alpha, alpha_subs)), disc) =
            rayon::join(
                || {
                    let evaluated: Vec<([f32; 3], bool, f32)> = rows
                        .par_iter()
                        // small tasks, for the same reason as the sensor pass's bands
                        .with_max_len(2)
                        .flat_map_iter(|&r| eval_row(r, &cols, step))
                        .collect();
                    let nodes: Vec<[f32; 3]> = evaluated.iter().map(|e| e.0).collect();
                    let valid: Vec<bool> = evaluated.iter().map(|e| e.1).collect();
                    let alpha: Vec<f32> = match split {
                        true => evaluated.iter().map(|e| e.2).collect(),
                        false => Vec::new(),
                    };
                    let curv = curvature(&nodes, gw, gh);
                    let tol = tol as f32;
                    let mut flagged = Vec::new();
                    let bands = gh.max(2) - 1;
                    if gw >= 2 && gh >= 2 {
                        // the test per cell in parallel, the numbering of the flagged ones in order
                        let mut more = vec![false; (gw - 1) * bands];
                        more.par_chunks_mut(gw - 1)
                            .enumerate()
                            .for_each(|(j, row)| {
                                for (i, m) in row.iter_mut().enumerate() {
                                    *m = cell_needs_more(&nodes, &valid, &curv, gw, i, j, tol)
                                        && !beyond_rim(
                                            cam,
                                            cols[i],
                                            cols[i + 1],
                                            rows[j],
                                            rows[j + 1],
                                        );
                                }
                            });
                        for (k, _) in more.iter().enumerate().filter(|(_, &m)| m) {
                            flagged.push((k % (gw - 1), k / (gw - 1)));
                        }
                    }
                    // flagged is in row-major order: each band's cells are one run
                    let band_subs: Vec<usize> = (0..=bands)
                        .map(|j| flagged.partition_point(|&(_, fj)| fj < j))
                        .collect();
                    let subs: Vec<SubGrid> = flagged
                        .par_iter()
                        .map(|&(i, j)| {
                            let sc = grid_nodes(cols[i], cols[i + 1], sub_step);
                            let sr = grid_nodes(rows[j], rows[j + 1], sub_step);
                            let (sw, sh) = (sc.len(), sr.len());
                            let ev: Vec<([f32; 3], bool, f32)> = sr
                                .iter()
                                .flat_map(|&r| eval_row(r, &sc, sub_step))
                                .collect();
                            let sn: Vec<[f32; 3]> = ev.iter().map(|e| e.0).collect();
                            let sv: Vec<bool> = ev.iter().map(|e| e.1).collect();
                            let salpha: Vec<f32> = match split {
                                true => ev.iter().map(|e| e.2).collect(),
                                false => Vec::new(),
                            };
                            let scurv = curvature(&sn, sw, sh);
                            let mut exact = vec![true; (sw - 1) * (sh - 1)];
                            if sub_step > 1 {
                                for jj in 0..sh - 1 {
                                    for ii in 0..sw - 1 {
                                        exact[jj * (sw - 1) + ii] =
                                            cell_needs_more(&sn, &sv, &scurv, sw, ii, jj, tol);
                                    }
                                }
                            }
                            SubGrid {
                                cell: i,
                                step: sub_step,
                                cols: sc,
                                rows: sr,
                                nodes: sn,
                                exact,
                                alpha: salpha,
                            }
                        })
                        .collect();
                    let exact_pixels = subs
                        .iter()
                        .map(|s| {
                            let sw = s.cols.len();
                            s.exact
                                .iter()
                                .enumerate()
                                .filter(|(_, &e)| e)
                                .map(|(k, _)| {
                                    let (ii, jj) = (k % (sw - 1), k / (sw - 1));
                                    (s.cols[ii + 1] - s.cols[ii]) * (s.rows[jj + 1] - s.rows[jj])
                                })
                                .sum::<usize>()
                        })
                        .sum();
                    // cells whose clouds change but whose sky interpolates: the clouds' opacity
                    // alone on a finer grid (no sky sampled there)
                    let mut alpha_cells = Vec::new();
                    if split && gw >= 2 && gh >= 2 {
                        let refined: std::collections::HashSet<(usize, usize)> =
                            flagged.iter().copied().collect();
                        for j in 0..gh - 1 {
                            for i in 0..gw - 1 {
                                if alpha_varies(&alpha, gw, i, j) && !refined.contains(&(i, j)) {
                                    alpha_cells.push((i, j));
                                }
                            }
                        }
                    }
                    let band_alpha: Vec<usize> = (0..=bands)
                        .map(|j| alpha_cells.partition_point(|&(_, fj)| fj < j))
                        .collect();
                    let alpha_subs: Vec<SubGrid> = alpha_cells
                        .par_iter()
                        .map(|&(i, j)| {
                            let sc = grid_nodes(cols[i], cols[i + 1], sub_step);
                            let sr = grid_nodes(rows[j], rows[j + 1], sub_step);
                            let w = world.expect("clouds come with a world");
                            let alpha = sr
                                .iter()
                                .flat_map(|&r| {
                                    sc.iter().map(move |&c| {
                                        cam.pixel_direction(c as f64, r as f64)
                                            .map_or(0.0, |d| w.direct_opacity(d) as f32)
                                    })
                                })
                                .collect();
                            SubGrid {
                                cell: i,
                                step: sub_step,
                                cols: sc,
                                rows: sr,
                                nodes: Vec::new(),
                                exact: Vec::new(),
                                alpha,
                            }
                        })
                        .collect();
                    (
                        nodes,
                        band_subs,
                        subs,
                        exact_pixels,
                        alpha,
                        (band_alpha, alpha_subs),
                    )
                },
                || {
                    if opts.sun_disc {
                        sun_disc_pixels(sky, cam)
                    } else {
                        Vec::new()
                    }
                },
            );
        // the bands of cells where a node sees a cloud
        let bands = rows.len().max(2) - 1;
        let cloudy: Vec<bool> = match split {
            false => Vec::new(),
            true => (0..bands)
                .map(|j| {
                    let gw = cols.len();
                    let in_rows = (j..(j + 2).min(rows.len()))
                        .any(|jj| alpha[jj * gw..(jj + 1) * gw].iter().any(|&a| a > 0.0));
                    let in_subs = subs[band_subs[j]..band_subs[j + 1]]
                        .iter()
                        .chain(&alpha_subs[band_alpha[j]..band_alpha[j + 1]])
                        .any(|s| s.alpha.iter().any(|&a| a > 0.0));
                    in_rows || in_subs
                })
                .collect(),
        };
        let cloud_radiance = sky
            .surroundings()
            .map_or(0.0, |w| w.cloud_radiance() as f32);
        SkyGrid {
            step,
            sky,
            cam,
            width: w,
            height: h,
            cols,
            rows,
            nodes,
            subs,
            band_subs,
            disc,
            exact_pixels,
            alpha,
            alpha_subs,
            band_alpha,
            cloudy,
            cloud_radiance,
        }
    }

    /// Pixels touched by the solar disc.
    pub fn sun_pixels(&self) -> usize {
        self.disc.len()
    }

    /// Coarse nodes evaluated.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Refined cells, sub-grid nodes evaluated, and pixels evaluated exactly (about: sub-cell
    /// edges shared by neighbours are counted once per cell).
    pub fn refinement(&self) -> (usize, usize, usize) {
        (
            self.subs.len(),
            self.subs.iter().map(|s| s.nodes.len()).sum(),
            self.exact_pixels,
        )
    }

    /// The whole image.
    pub fn to_image(&self) -> StokesImage {
        let mut out = StokesImage::zeros(self.width, self.height);
        out.par_rows(|r, a, b, c| self.fill_row(r, a, b, c));
        out
    }

    /// Index of the node interval holding `x` in `nodes` (the last interval holds the end).
    #[inline]
    pub(super) fn interval(nodes: &[usize], step: usize, x: usize) -> usize {
        (x / step).min(nodes.len() - 2)
    }
}

/// Fills `out[k]` for columns c0..c_end of one row by linear interpolation between `left` (at c0)
/// and `right` (at c1).
#[inline(always)]
pub(super) fn lerp_span(
    out: [&mut [f32]; 3],
    left: [f32; 3],
    right: [f32; 3],
    c0: usize,
    c1: usize,
    c_end: usize,
) {
    // x as f32 read from a table, so that the loop vectorises (the same values)
    const XS: [f32; 64] = {
        let mut t = [0f32; 64];
        let mut i = 0;
        while i < 64 {
            t[i] = i as f32;
            i += 1;
        }
        t
    };
    let inv = 1.0 / (c1 - c0) as f32;
    for (k, o) in out.into_iter().enumerate() {
        let (l, d) = (left[k], right[k] - left[k]);
        let o = &mut o[c0..c_end];
        if o.len() <= XS.len() {
            for (v, &x) in o.iter_mut().zip(&XS) {
                *v = l + d * (x * inv);
            }
        } else {
            for (x, v) in o.iter_mut().enumerate() {
                *v = l + d * (x as f32 * inv);
            }
        }
    }
}

/// The full-width cells 0..gw − 2 of row band `j` (columns 0..`full`): each plane bilinear
/// between the nodes of rows j and j + 1 (weight `fy`), `fx[x]` = x/step across a cell; the
/// same arithmetic as `lerp3` then `lerp_span`, one plane at a time.
#[allow(clippy::too_many_arguments)]
pub(super) fn interp_cells(
    s0: &mut [f32],
    s1: &mut [f32],
    s2: &mut [f32],
    nodes: &[[f32; 3]],
    gw: usize,
    j: usize,
    fy: f32,
    fx: &[f32],
    full: usize,
) {
    let (top, bottom) = (
        nodes[j * gw..(j + 1) * gw].as_flattened(),
        nodes[(j + 1) * gw..(j + 2) * gw].as_flattened(),
    );
    // the row's node values and their differences to the next node, all planes interleaved
    // (v[3i + p], d[3i + p]), in two loops over whole vectors: a cell then needs two broadcasts
    // (a per-thread buffer: neither an allocation nor zeroing per row)
    thread_local! {
        static NODE_ROW: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    NODE_ROW.with_borrow_mut(|buf| {
        let n = top.len();
        if buf.len() < 2 * n {
            buf.resize(2 * n, 0.0);
        }
        let (v, d) = buf.split_at_mut(n);
        let (v, d) = (&mut v[..n], &mut d[..n]);
        for k in 0..n {
            v[k] = top[k] + (bottom[k] - top[k]) * fy;
        }
        for k in 0..n - 3 {
            d[k] = v[k + 3] - v[k];
        }
        interp_planes([s0, s1, s2], v, d, fx, full);
    });
}

/// The planes of [`interp_cells`] from the node row `v` and its differences `d`.
pub(super) fn interp_planes(s: [&mut [f32]; 3], v: &[f32], d: &[f32], fx: &[f32], full: usize) {
    for (p, out) in s.into_iter().enumerate() {
        let out = &mut out[..full];
        // the default grid's 16-pixel cells as whole vectors, written out: left to itself the
        // loop vectoriser spreads the cells over the lanes and scatters (slower than scalar)
        match <&[f32; 16]>::try_from(fx) {
            Ok(fx) => interp16(out, v, d, p, fx),
            Err(_) => interp_plane(out, v, d, p, fx),
        }
    }
}

crate::simd_dispatch! {
    /// [`interp_plane`] for 16-pixel cells.
    pub(super) fn interp16 = {
        avx512: interp16_avx512,
        avx2: interp16_avx2,
        plain: interp16_plain,
    }(out: &mut [f32], v: &[f32], d: &[f32], p: usize, fx: &[f32; 16])
}

pub(super) fn interp16_plain(out: &mut [f32], v: &[f32], d: &[f32], p: usize, fx: &[f32; 16]) {
    interp_plane(out, v, d, p, fx);
}

/// One plane of [`interp_cells`], any cell width (`fx.len()`): cell i is v[3i + p] +
/// d[3i + p] · fx.
pub(super) fn interp_plane(out: &mut [f32], v: &[f32], d: &[f32], p: usize, fx: &[f32]) {
    for (i, chunk) in out.chunks_exact_mut(fx.len()).enumerate() {
        let (l, d) = (v[3 * i + p], d[3 * i + p]);
        for (o, &f) in chunk.iter_mut().zip(fx) {
            *o = l + d * f;
        }
    }
}

/// [`interp_plane`] for 16-pixel cells, one AVX-512 vector per cell (separate multiply and add,
/// as the scalar code: the same bits).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
pub(super) fn interp16_avx512(out: &mut [f32], v: &[f32], d: &[f32], p: usize, fx: &[f32; 16]) {
    use std::arch::x86_64::*;
    let cells = out.len() / 16;
    assert!(p < 3 && 3 * cells <= d.len() && d.len() <= v.len());
    // SAFETY: 16 floats read from `fx` and written to each of the `cells` 16-float chunks of
    // `out`; v and d read at 3i + p < 3 cells ≤ d.len() ≤ v.len() (asserted)
    unsafe {
        let f = _mm512_loadu_ps(fx.as_ptr());
        let (v, d, o) = (v.as_ptr().add(p), d.as_ptr().add(p), out.as_mut_ptr());
        for i in 0..cells {
            let l = _mm512_set1_ps(*v.add(3 * i));
            let dd = _mm512_set1_ps(*d.add(3 * i));
            _mm512_storeu_ps(o.add(16 * i), _mm512_add_ps(l, _mm512_mul_ps(dd, f)));
        }
    }
}

/// [`interp16_avx512`] with two AVX vectors per cell.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(super) fn interp16_avx2(out: &mut [f32], v: &[f32], d: &[f32], p: usize, fx: &[f32; 16]) {
    use std::arch::x86_64::*;
    let cells = out.len() / 16;
    assert!(p < 3 && 3 * cells <= d.len() && d.len() <= v.len());
    // SAFETY: as in `interp16_avx512`
    unsafe {
        let (fa, fb) = (
            _mm256_loadu_ps(fx.as_ptr()),
            _mm256_loadu_ps(fx.as_ptr().add(8)),
        );
        let (v, d, o) = (v.as_ptr().add(p), d.as_ptr().add(p), out.as_mut_ptr());
        for i in 0..cells {
            let l = _mm256_set1_ps(*v.add(3 * i));
            let dd = _mm256_set1_ps(*d.add(3 * i));
            let o = o.add(16 * i);
            _mm256_storeu_ps(o, _mm256_add_ps(l, _mm256_mul_ps(dd, fa)));
            _mm256_storeu_ps(o.add(8), _mm256_add_ps(l, _mm256_mul_ps(dd, fb)));
        }
    }
}

#[inline(always)]
pub(super) fn lerp3(a: [f32; 3], b: [f32; 3], f: f32) -> [f32; 3] {
    [
        a[0] + (b[0] - a[0]) * f,
        a[1] + (b[1] - a[1]) * f,
        a[2] + (b[2] - a[2]) * f,
    ]
}

impl SkyGrid<'_> {
    /// Lays the clouds over row `r` (band `j`) of the interpolated clear sky: their opacity α
    /// bilinear between the nodes (the refined cells' own nodes where there are some), then
    /// S0 ← S0 + α (L_cloud − S0), S1,2 ← (1 − α) S1,2.
    fn lay_clouds(&self, r: usize, j: usize, s0: &mut [f32], s1: &mut [f32], s2: &mut [f32]) {
        let w = self.width;
        thread_local! {
            static ALPHA_ROW: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        ALPHA_ROW.with_borrow_mut(|a| {
            a.resize(w, 0.0);
            let spans = self.alpha_row(r, j, a);
            let lc = self.cloud_radiance;
            // only the cells with a cloud at a corner
            for (c0, c1) in spans {
                for c in c0..c1 {
                    let al = a[c];
                    s0[c] += al * (lc - s0[c]);
                    s1[c] *= 1.0 - al;
                    s2[c] *= 1.0 - al;
                }
            }
        });
    }

    /// The clouds' opacity along row `r` (band `j`) into `a`, and the column spans where it
    /// may be above 0 (in order, merged); elsewhere `a` is left as it was.
    fn alpha_row(&self, r: usize, j: usize, a: &mut [f32]) -> Vec<(usize, usize)> {
        let mut spans: Vec<(usize, usize)> = Vec::new();
        let mut extra: Vec<(usize, usize)> = Vec::new();
        let (w, gw) = (self.width, self.cols.len());
        let (r0, r1) = (self.rows[j], self.rows[j + 1]);
        let fy = (r - r0) as f32 / (r1 - r0) as f32;
        let at = |i: usize| {
            let (t, b) = (self.alpha[j * gw + i], self.alpha[(j + 1) * gw + i]);
            t + (b - t) * fy
        };
        for i in 0..gw - 1 {
            let (c0, c1) = (self.cols[i], self.cols[i + 1]);
            let end = if i + 2 == gw { w } else { c1 };
            let (l, rr) = (at(i), at(i + 1));
            if l == 0.0 && rr == 0.0 {
                continue; // a refined cell with a cloud inside adds its own span below
            }
            let inv = 1.0 / (c1 - c0) as f32;
            for (x, v) in a[c0..end].iter_mut().enumerate() {
                *v = l + (rr - l) * (x as f32 * inv);
            }
            match spans.last_mut() {
                Some(last) if last.1 >= c0 => last.1 = last.1.max(end),
                _ => spans.push((c0, end)),
            }
        }
        let refined = self.subs[self.band_subs[j]..self.band_subs[j + 1]].iter();
        let alpha_only = self.alpha_subs[self.band_alpha[j]..self.band_alpha[j + 1]].iter();
        for sg in refined.chain(alpha_only) {
            let sw = sg.cols.len();
            let (jj, fy, cells) = sg.row(r, r0, &self.cols);
            let n = |x: usize, y: usize| sg.alpha[y * sw + x];
            for (ii, a0, a1, a_end) in cells {
                let l = n(ii, jj) + (n(ii, jj + 1) - n(ii, jj)) * fy;
                let rr = n(ii + 1, jj) + (n(ii + 1, jj + 1) - n(ii + 1, jj)) * fy;
                let inv = 1.0 / (a1 - a0) as f32;
                for (x, v) in a[a0..a_end].iter_mut().enumerate() {
                    *v = l + (rr - l) * (x as f32 * inv);
                }
                if l > 0.0 || rr > 0.0 {
                    extra.push((a0, a_end));
                }
            }
        }
        // the refined cells' spans into the coarse ones, in order
        if !extra.is_empty() {
            let mut all = std::mem::take(&mut spans);
            all.extend(extra);
            all.sort_unstable();
            for (c0, c1) in all {
                match spans.last_mut() {
                    Some(last) if last.1 >= c0 => last.1 = last.1.max(c1),
                    _ => spans.push((c0, c1)),
                }
            }
        }
        spans
    }
}

impl StokesRows for SkyGrid<'_> {
    fn width(&self) -> usize {
        self.width
    }
    fn height(&self) -> usize {
        self.height
    }
    fn fill_row(&self, r: usize, s0: &mut [f32], s1: &mut [f32], s2: &mut [f32]) {
        let (w, gw) = (self.width, self.cols.len());
        let step = self.step;
        // columns evaluated exactly, gathered so that the row evaluator gets whole chunks
        let mut exact: Vec<usize> = Vec::new();
        if gw < 2 || self.rows.len() < 2 {
            exact.extend(0..w);
        } else {
            let j = Self::interval(&self.rows, step, r);
            let (r0, r1) = (self.rows[j], self.rows[j + 1]);
            let fy = (r - r0) as f32 / (r1 - r0) as f32;
            // every cell by interpolation first (the full-width cells in one tight loop per
            // plane, built for the CPU's vector units), then the refined cells overwritten
            let full = (gw - 2) * step; // cells 0..gw−2 are `step` wide, the last one narrower
            let (mut buf, mut heap) = ([0f32; 64], Vec::new());
            let fx: &mut [f32] = if step <= buf.len() {
                &mut buf[..step]
            } else {
                heap.resize(step, 0.0);
                &mut heap
            };
            for (x, f) in fx.iter_mut().enumerate() {
                *f = x as f32 / step as f32;
            }
            interp_cells(s0, s1, s2, &self.nodes, gw, j, fy, fx, full);
            let v = |i: usize| lerp3(self.nodes[j * gw + i], self.nodes[(j + 1) * gw + i], fy);
            lerp_span(
                [&mut *s0, &mut *s1, &mut *s2],
                v(gw - 2),
                v(gw - 1),
                self.cols[gw - 2],
                self.cols[gw - 1],
                w,
            );
            for sg in &self.subs[self.band_subs[j]..self.band_subs[j + 1]] {
                let sw = sg.cols.len();
                let (jj, fy, cells) = sg.row(r, r0, &self.cols);
                for (ii, a0, a1, a_end) in cells {
                    if sg.exact[jj * (sw - 1) + ii] {
                        exact.extend(a0..a_end);
                    } else {
                        let n = |x: usize, y: usize| sg.nodes[y * sw + x];
                        let left = lerp3(n(ii, jj), n(ii, jj + 1), fy);
                        let right = lerp3(n(ii + 1, jj), n(ii + 1, jj + 1), fy);
                        lerp_span([&mut *s0, &mut *s1, &mut *s2], left, right, a0, a1, a_end);
                    }
                }
            }
        }
        if !self.cloudy.is_empty() && self.rows.len() >= 2 && self.cols.len() >= 2 {
            let j = Self::interval(&self.rows, step, r);
            if self.cloudy[j] {
                self.lay_clouds(r, j, s0, s1, s2);
            }
        }
        stokes_at(
            self.sky,
            self.cam,
            r,
            &exact,
            [&mut *s0, &mut *s1, &mut *s2],
        );
        // the camera mask's blocked pixels are black, edges and all
        if let Some(m) = self.sky.surroundings().and_then(|w| w.world().mask_row(r)) {
            for (c, _) in m.iter().enumerate().filter(|(_, &v)| v == 0) {
                (s0[c], s1[c], s2[c]) = (0.0, 0.0, 0.0);
            }
        }
        // the solar disc, exactly as render_stokes adds it
        let lo = self.disc.partition_point(|&(k, _)| k < r * w);
        for &(k, add) in self.disc[lo..]
            .iter()
            .take_while(|&&(k, _)| k < (r + 1) * w)
        {
            s0[k - r * w] += add;
        }
    }
}

//! Vertex positioning from per-triangle rotations (Popa et al. 2009 §5.4).
//!
//! Formulation used: the gradient-domain (Poisson) form that Botsch et al. 2006 show equivalent to the
//! Sumner–Popović deformation-transfer objective ‖Ṽ V⁻¹ − R‖²_F with the virtual fourth vertex eliminated:
//!
//! ```text
//!   min_x  Σ_t A_t ‖F_t(x) − R_t P_t‖²_F      F_t(x) = Σ_{j∈t} x_j ∇φ_jᵀ   (deformation gradient of t)
//! ```
//!
//! with A_t, ∇φ_j and the tangent projector P_t taken from the *original* frame. Its normal equations are
//! K x = b with K the cotangent stiffness matrix of the original frame. We solve for the displacement
//! d = x − x₀ instead of x: since K x₀ = Σ_t A_t P_t ∇φ_i, the right-hand side becomes
//! b_i = Σ_{t∋i} A_t (R_t − I) ∇φ_i, which is exactly zero when every R_t is the identity. That makes "no
//! anchors ⇒ output equals input" hold bit for bit, and keeps round-off relative to the fold displacement
//! rather than to the garment's world coordinates.
//!
//! K depends on the original frame only, not on the rotations, so each frame is factorised once (sparse
//! supernodal Cholesky, faer) and the factor is reused by every stretch-reduction pass; the symbolic analysis
//! (AMD ordering, elimination tree) depends on connectivity only and is shared by all frames.
//!
//! **Shape screen.** The rotation field is only known up to what the anchors say about folds; integrated over a
//! whole garment, its smooth part (weights diffuse far from every anchor) adds up to a drift of the garment's
//! overall shape — a bend, a shrink, a swing — that the capture did not see. The capture is trustworthy exactly
//! at long wavelengths, so the displacement is screened:
//!
//! ```text
//!   (K + λ M) d = b,      λ = (2π / ℓ_c)²,      M = lumped (barycentric) vertex areas
//! ```
//!
//! An eigenmode of K with wavelength ℓ (K u = (2π/ℓ)² M u) is scaled by 1 / (1 + (ℓ/ℓ_c)²): folds, shorter
//! than the cutoff ℓ_c, pass; the garment's shape, many cutoffs long, stays the captured one. ℓ_c is a length of the
//! sequence (a multiple of its detail scale, [`crate::spacetime::shape`]), the same in every frame. The
//! system stays SPD and depends on the original frame only (one factor per frame, reused by the stretch
//! passes), b = 0 still gives d = 0 bit for bit, and no vertex needs to be fixed: the translational null
//! space is gone. Only vertices without triangles (no area, no stiffness) are fixed.
//!
//! Without the screen (`shape_cutoff` off), one vertex per connected component is fixed to remove the
//! translational null space. By default the component is then translated so that its area-weighted mean
//! displacement is zero (the garment stays centred on the capture instead of hanging from an arbitrary
//! vertex); [`Pinning::Vertex`] keeps the fixed vertex exactly in place instead.

use crate::error::{Error, Result};
use crate::mesh::{Frame, Topology, NONE};
use crate::vec3::{self, M3, V3};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, Par, Side};
use std::sync::Arc;

/// How the translational degree of freedom of each connected component is removed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Pinning {
    /// Fix the lowest-index vertex of each component in the solve, then translate the component so that its
    /// area-weighted mean displacement is zero.
    #[default]
    Centroid,
    /// Fix the lowest-index vertex of each component and leave it exactly where it was.
    Vertex,
}

/// Connectivity-only part of the positioning system, shared by all frames: the sparsity pattern of the reduced
/// stiffness matrix (lower triangle, CSC), a per-triangle scatter map into it, and the symbolic factorisation.
pub struct PositionSystem {
    topo: Arc<Topology>,
    pinning: Pinning,
    /// Cutoff wavelength ℓ_c of the shape screen in mean edge lengths, or None for the unscreened system.
    shape_cutoff: Option<f64>,
    /// Row of each vertex in the reduced system, or NONE for pinned vertices.
    free_index: Vec<u32>,
    n_free: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// For triangle corner pairs (0,0),(1,1),(2,2),(0,1),(1,2),(2,0): index into the values array, or NONE.
    scatter: Vec<[u32; 6]>,
    symbolic: SymbolicCholesky<usize>,
    /// The three-column triangular solves' view of the factor structure (None: not supernodal; faer solves).
    solve_plan: Option<super::factor_solve::SolvePlan>,
}

const PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (2, 0)];

impl PositionSystem {
    /// Builds the pattern and the symbolic Cholesky analysis (AMD ordering) once per sequence.
    /// `shape_cutoff` is the screen's cutoff wavelength ℓ_c in the input's units (None: no screen, `pinning`
    /// removes the null space instead).
    pub fn new(topo: Arc<Topology>, pinning: Pinning, shape_cutoff: Option<f64>) -> Result<Self> {
        if let Some(l) = shape_cutoff {
            if !(l.is_finite() && l > 0.0) {
                return Err(Error::param(
                    "shape_cutoff",
                    format!("must be a finite wavelength > 0, got {l}"),
                ));
            }
        }
        let nv = topo.n_vertices();
        let mut pinned_component = vec![false; topo.n_components()];
        let mut free_index = vec![NONE; nv];
        let mut n_free = 0usize;
        for (v, fi) in free_index.iter_mut().enumerate() {
            let c = topo.vertex_component()[v] as usize;
            let pinned = if shape_cutoff.is_some() {
                topo.vertex_triangles(v).is_empty() // no area: nothing screens it
            } else {
                !pinned_component[c] // lowest index of its component
            };
            if pinned {
                pinned_component[c] = true;
            } else {
                *fi = n_free as u32;
                n_free += 1;
            }
        }
        // Lower-triangle entries (row >= col) of the reduced stiffness matrix.
        let mut entries: Vec<(u32, u32)> = Vec::with_capacity(topo.n_triangles() * 6);
        for tri in topo.triangles() {
            for (a, b) in PAIRS {
                let (fa, fb) = (free_index[tri[a] as usize], free_index[tri[b] as usize]);
                if fa != NONE && fb != NONE {
                    entries.push((fa.min(fb), fa.max(fb)));
                }
            }
        }
        entries.sort_unstable();
        entries.dedup();
        let mut col_ptr = vec![0usize; n_free + 1];
        for &(c, _) in &entries {
            col_ptr[c as usize + 1] += 1;
        }
        for c in 0..n_free {
            col_ptr[c + 1] += col_ptr[c];
        }
        let row_idx: Vec<usize> = entries.iter().map(|&(_, r)| r as usize).collect();
        let scatter = topo
            .triangles()
            .iter()
            .map(|tri| {
                PAIRS.map(|(a, b)| {
                    let (fa, fb) = (free_index[tri[a] as usize], free_index[tri[b] as usize]);
                    if fa == NONE || fb == NONE {
                        return NONE;
                    }
                    let (c, r) = (fa.min(fb) as usize, fa.max(fb) as usize);
                    let col = &row_idx[col_ptr[c]..col_ptr[c + 1]];
                    (col_ptr[c] + col.binary_search(&r).expect("entry in pattern")) as u32
                })
            })
            .collect();
        let symbolic = {
            let sym =
                SymbolicSparseColMatRef::new_checked(n_free, n_free, &col_ptr, None, &row_idx);
            factorize_symbolic_cholesky(
                sym,
                Side::Lower,
                SymmetricOrdering::Amd,
                Default::default(),
            )
            .map_err(|e| Error::numeric("positioning: symbolic Cholesky", format!("{e:?}")))?
        };
        let solve_plan = super::factor_solve::SolvePlan::new(&symbolic);
        Ok(PositionSystem {
            topo,
            pinning,
            shape_cutoff,
            free_index,
            n_free,
            col_ptr,
            row_idx,
            scatter,
            symbolic,
            solve_plan,
        })
    }

    pub fn topology(&self) -> &Arc<Topology> {
        &self.topo
    }

    /// Assembles the lower triangle of the reduced cotangent stiffness matrix of one original frame (values in
    /// the pattern of [`PositionSystem::pattern`]), with the per-triangle gradients, areas and unit normals.
    #[allow(clippy::type_complexity)]
    pub fn assemble(&self, rest: &[V3]) -> Result<(Vec<f64>, Vec<[V3; 3]>, Vec<f64>, Vec<V3>)> {
        self.assemble_held(rest, None)
    }

    /// [`PositionSystem::assemble`] with the screen scaled per vertex by `hold` (1 or `None`: the full screen;
    /// see [`crate::spacetime::shape::lost_area::Trace::hold`]).
    #[allow(clippy::type_complexity)]
    pub fn assemble_held(
        &self,
        rest: &[V3],
        hold: Option<&[f64]>,
    ) -> Result<(Vec<f64>, Vec<[V3; 3]>, Vec<f64>, Vec<V3>)> {
        let topo = &self.topo;
        let mut grads = Vec::with_capacity(topo.n_triangles());
        let mut areas = Vec::with_capacity(topo.n_triangles());
        let mut normals = Vec::with_capacity(topo.n_triangles());
        let mut values = vec![0.0f64; self.row_idx.len()];
        // Screen weight λ = (2π / ℓ_c)² (0 without the screen).
        let screen = self
            .shape_cutoff
            .map_or(0.0, |l| (2.0 * std::f64::consts::PI / l).powi(2));
        for (t, &tri) in topo.triangles().iter().enumerate() {
            let [a, b, c] = tri.map(|i| rest[i as usize]);
            let n = vec3::cross(vec3::sub(b, a), vec3::sub(c, a));
            let twice_area = vec3::norm(n);
            if !twice_area.is_finite() || twice_area <= 0.0 {
                return Err(Error::mesh(format!("triangle {t} is degenerate")));
            }
            let nh = vec3::scale(n, 1.0 / twice_area);
            // ∇φ_j = n̂ × e_j / (2A), e_j the edge opposite corner j (counter-clockwise).
            let g = [
                vec3::scale(vec3::cross(nh, vec3::sub(c, b)), 1.0 / twice_area),
                vec3::scale(vec3::cross(nh, vec3::sub(a, c)), 1.0 / twice_area),
                vec3::scale(vec3::cross(nh, vec3::sub(b, a)), 1.0 / twice_area),
            ];
            let area = 0.5 * twice_area;
            for (k, (i, j)) in PAIRS.iter().enumerate() {
                let slot = self.scatter[t][k];
                if slot != NONE {
                    // The first three pairs are the diagonal: each corner gets a third of the area as mass.
                    let mass = if k < 3 {
                        screen * area / 3.0 * hold.map_or(1.0, |h| h[tri[*i] as usize])
                    } else {
                        0.0
                    };
                    values[slot as usize] += area * vec3::dot(g[*i], g[*j]) + mass;
                }
            }
            grads.push(g);
            areas.push(area);
            normals.push(nh);
        }
        Ok((values, grads, areas, normals))
    }

    /// Sparsity pattern (CSC, lower triangle) of the reduced system: (column pointers, row indices).
    pub fn pattern(&self) -> (&[usize], &[usize]) {
        (&self.col_ptr, &self.row_idx)
    }

    /// Row of each vertex in the reduced system, or `NONE` for pinned vertices.
    pub fn free_index(&self) -> &[u32] {
        &self.free_index
    }

    /// Non-zeros of the Cholesky factor (memory of one numeric factorisation is 8 bytes each).
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Assembles and factorises the stiffness matrix of one original frame.
    pub fn factor_frame<'a>(&'a self, rest: &'a [V3]) -> Result<FramePositioner<'a>> {
        self.factor_frame_held(rest, None)
    }

    /// [`PositionSystem::factor_frame`] with the screen scaled per vertex by `hold`.
    pub fn factor_frame_held<'a>(
        &'a self,
        rest: &'a [V3],
        hold: Option<&[f64]>,
    ) -> Result<FramePositioner<'a>> {
        if let Some(h) = hold {
            if h.len() != rest.len() {
                return Err(Error::mesh(format!(
                    "screen weights for {} vertices, frame has {}",
                    h.len(),
                    rest.len()
                )));
            }
        }
        let (values, grads, areas, normals) = self.assemble_held(rest, hold)?;
        let l_values = Arc::new(self.factorize(&values)?);
        Ok(self.positioner(rest, l_values, grads, areas, normals))
    }

    fn positioner<'a>(
        &'a self,
        rest: &'a [V3],
        l_values: Arc<Vec<f64>>,
        grads: Vec<[V3; 3]>,
        areas: Vec<f64>,
        normals: Vec<V3>,
    ) -> FramePositioner<'a> {
        let topo = &self.topo;
        let vertex_area = {
            let mut va = vec![0.0; topo.n_vertices()];
            for (t, tri) in topo.triangles().iter().enumerate() {
                for &v in tri {
                    va[v as usize] += areas[t] / 3.0;
                }
            }
            va
        };
        FramePositioner {
            sys: self,
            rest,
            grads,
            areas,
            normals,
            l_values,
            vertex_area,
        }
    }

    /// Numeric Cholesky factor of the reduced stiffness values `values` (in the pattern's order).
    fn factorize(&self, values: &[f64]) -> Result<Vec<f64>> {
        let stack_req = self
            .symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
        let mut buf = MemBuffer::try_new(stack_req).map_err(|_| {
            Error::numeric("positioning", "out of memory for the Cholesky workspace")
        })?;
        let mut l_values = vec![0.0f64; self.symbolic.len_val()];
        {
            let sym = SymbolicSparseColMatRef::new_checked(
                self.n_free,
                self.n_free,
                &self.col_ptr,
                None,
                &self.row_idx,
            );
            let k = SparseColMatRef::new(sym, values);
            self.symbolic
                .factorize_numeric_llt::<f64>(
                    &mut l_values,
                    k,
                    Side::Lower,
                    Default::default(),
                    Par::Seq,
                    MemStack::new(&mut buf),
                    Default::default(),
                )
                .map_err(|e| {
                    Error::numeric(
                        "positioning: Cholesky",
                        format!("stiffness matrix is not positive definite ({e:?})"),
                    )
                })?;
        }
        Ok(l_values)
    }
}

/// One original frame's factorised positioning system; solves for any set of per-triangle rotations.
pub struct FramePositioner<'a> {
    sys: &'a PositionSystem,
    rest: &'a [V3],
    grads: Vec<[V3; 3]>,
    areas: Vec<f64>,
    normals: Vec<V3>,
    l_values: Arc<Vec<f64>>,
    vertex_area: Vec<f64>,
}

impl FramePositioner<'_> {
    /// Unit normals of the original frame's triangles.
    pub fn rest_normals(&self) -> &[V3] {
        &self.normals
    }
    pub fn rest_areas(&self) -> &[f64] {
        &self.areas
    }
    /// The original frame's positions.
    pub fn rest(&self) -> &[V3] {
        self.rest
    }

    /// Positions whose deformation gradients best match `rotations` (one per triangle) in the least-squares
    /// sense of the module documentation.
    pub fn solve(&self, rotations: &[M3]) -> Frame {
        let mut rhs = self.rhs(rotations);
        self.solve_in_place(&mut rhs);
        self.finish(&rhs)
    }

    /// Right-hand side Σ_t A_t (R_t − I) ∇φ_i of the displacement system (free rows × 3).
    pub fn rhs(&self, rotations: &[M3]) -> Mat<f64> {
        let sys = self.sys;
        let topo = &sys.topo;
        let mut rhs = Mat::<f64>::zeros(sys.n_free, 3);
        for (t, tri) in topo.triangles().iter().enumerate() {
            let r = &rotations[t];
            let a = self.areas[t];
            for (k, &v) in tri.iter().enumerate() {
                let fi = sys.free_index[v as usize];
                if fi == NONE {
                    continue;
                }
                let g = self.grads[t][k];
                let rg = vec3::mat_vec(r, g);
                for c in 0..3 {
                    rhs[(fi as usize, c)] += a * (rg[c] - g[c]);
                }
            }
        }
        rhs
    }

    /// Overwrites `rhs` with K⁻¹ rhs using the frame's factor (three columns in one sweep over the factor, the
    /// sequence's solve plan cutting it into subtrees solved in parallel, [`super::factor_solve`]; faer's
    /// general solve otherwise).
    pub fn solve_in_place(&self, rhs: &mut Mat<f64>) {
        let sys = self.sys;
        if let Some(plan) = &sys.solve_plan {
            if plan.solve3(&sys.symbolic, &self.l_values, rhs) {
                return;
            }
        }
        self.solve_in_place_faer(rhs);
    }

    /// faer's general supernodal solve (any number of columns); the reference for the three-column sweep.
    pub fn solve_in_place_faer(&self, rhs: &mut Mat<f64>) {
        let sys = self.sys;
        let llt = LltRef::<usize, f64>::new(&sys.symbolic, &self.l_values);
        let mut buf = MemBuffer::new(
            sys.symbolic
                .solve_in_place_scratch::<f64>(rhs.ncols(), Par::Seq),
        );
        llt.solve_in_place_with_conj(Conj::No, rhs.as_mut(), Par::Seq, MemStack::new(&mut buf));
    }

    /// Output positions from the solved displacements of the free vertices (applies the pinning policy when
    /// there is no screen).
    fn finish(&self, rhs: &Mat<f64>) -> Frame {
        let sys = self.sys;
        let topo = &sys.topo;
        let mut d = vec![[0.0f64; 3]; topo.n_vertices()];
        for (v, dv) in d.iter_mut().enumerate() {
            let fi = sys.free_index[v];
            if fi != NONE {
                *dv = [
                    rhs[(fi as usize, 0)],
                    rhs[(fi as usize, 1)],
                    rhs[(fi as usize, 2)],
                ];
            }
        }
        if sys.shape_cutoff.is_none() && sys.pinning == Pinning::Centroid {
            let nc = topo.n_components();
            let mut sum = vec![[0.0f64; 3]; nc];
            let mut wsum = vec![0.0f64; nc];
            for (v, dv) in d.iter().enumerate() {
                let c = topo.vertex_component()[v] as usize;
                sum[c] = vec3::add(sum[c], vec3::scale(*dv, self.vertex_area[v]));
                wsum[c] += self.vertex_area[v];
            }
            for (v, dv) in d.iter_mut().enumerate() {
                let c = topo.vertex_component()[v] as usize;
                if wsum[c] > 0.0 {
                    *dv = vec3::sub(*dv, vec3::scale(sum[c], 1.0 / wsum[c]));
                }
            }
        }
        self.rest
            .iter()
            .zip(&d)
            .map(|(x, dv)| vec3::add(*x, *dv))
            .collect()
    }

    pub fn topology(&self) -> &Arc<Topology> {
        &self.sys.topo
    }
}

//! Clustered principal component analysis of transfer (Sloan, Hall, Hart & Snyder 2003,
//! "Clustered principal components for precomputed radiance transfer"): the points of a block
//! are split into `K` clusters, and within each cluster a point's transfer vector is its
//! cluster's mean plus `M` weighted principal directions. Relighting then costs `K·(M+1)` dot
//! products per frame and `M` multiply-adds per point and colour instead of `order²`.
//!
//! The clusters come from k-means (k-means++ seeding from a keyed PCG stream, Lloyd
//! iterations), then CPCA's own refinement: points move to the cluster whose mean and basis
//! reconstruct them best, and each cluster's mean and basis are recomputed (principal
//! directions from the eigenvectors of its covariance, `nalgebra`), for a few rounds. Every
//! sum runs over points in index order, so the result is the same on any thread count.

use nalgebra::{DMatrix, SymmetricEigen};
use prt_bakefile::Cpca;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;

/// How to compress one block.
#[derive(Clone, Copy, Debug)]
pub struct CpcaOptions {
    /// Clusters `K` (at most the number of points).
    pub clusters: usize,
    /// Basis vectors per cluster `M`; `None`: the fewest that bring the block's relative L2
    /// error to `error_target` (at most `D`).
    pub components: Option<usize>,
    /// The relative L2 error the choice of `M` aims at (with `components: None`).
    pub error_target: f64,
    /// Lloyd iterations of the k-means start.
    pub kmeans_iterations: usize,
    /// CPCA refinement rounds (reassign by reconstruction error, recompute bases).
    pub refinements: usize,
    /// Seed of the k-means++ start.
    pub seed: u64,
}

impl Default for CpcaOptions {
    fn default() -> Self {
        Self {
            clusters: 16,
            components: None,
            error_target: 0.01,
            kmeans_iterations: 12,
            refinements: 2,
            seed: 0,
        }
    }
}

/// One cluster's model: mean and principal directions (unit, by decreasing variance), and
/// the variances along all `D` directions.
struct Model {
    mean: Vec<f64>,
    basis: Vec<Vec<f64>>,
    variances: Vec<f64>,
}

fn sq_dist(a: &[f32], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| (f64::from(x) - y).powi(2))
        .sum()
}

/// The mean and the full eigen-decomposition of the covariance of `members`.
fn fit(data: &[f32], d: usize, members: &[usize]) -> Model {
    let n = members.len().max(1) as f64;
    let mut mean = vec![0.0f64; d];
    for &p in members {
        for (m, &x) in mean.iter_mut().zip(&data[p * d..(p + 1) * d]) {
            *m += f64::from(x);
        }
    }
    mean.iter_mut().for_each(|m| *m /= n);
    let mut cov = DMatrix::<f64>::zeros(d, d);
    let mut centred = vec![0.0f64; d];
    for &p in members {
        for ((c, &x), m) in centred.iter_mut().zip(&data[p * d..(p + 1) * d]).zip(&mean) {
            *c = f64::from(x) - m;
        }
        for i in 0..d {
            let ci = centred[i];
            if ci == 0.0 {
                continue;
            }
            for j in i..d {
                cov[(i, j)] += ci * centred[j];
            }
        }
    }
    for i in 0..d {
        for j in i..d {
            let v = cov[(i, j)] / n;
            cov[(i, j)] = v;
            cov[(j, i)] = v;
        }
    }
    let eig = SymmetricEigen::new(cov);
    let mut order: Vec<usize> = (0..d).collect();
    order.sort_by(|&a, &b| {
        eig.eigenvalues[b]
            .total_cmp(&eig.eigenvalues[a])
            .then(a.cmp(&b))
    });
    let basis = order
        .iter()
        .map(|&k| {
            let mut v: Vec<f64> = eig.eigenvectors.column(k).iter().copied().collect();
            // A fixed sign (largest component positive), so the output does not depend on
            // the solver's arbitrary one.
            let big = v
                .iter()
                .copied()
                .fold(0.0f64, |a, x| if x.abs() > a.abs() { x } else { a });
            if big < 0.0 {
                v.iter_mut().for_each(|x| *x = -*x);
            }
            v
        })
        .collect();
    let variances = order.iter().map(|&k| eig.eigenvalues[k].max(0.0)).collect();
    Model {
        mean,
        basis,
        variances,
    }
}

/// Squared reconstruction error of point `x` by `model` with `m` directions.
fn residual(x: &[f32], model: &Model, m: usize) -> f64 {
    let centred: Vec<f64> = x
        .iter()
        .zip(&model.mean)
        .map(|(&v, mu)| f64::from(v) - mu)
        .collect();
    let total: f64 = centred.iter().map(|c| c * c).sum();
    let captured: f64 = model.basis[..m]
        .iter()
        .map(|b| {
            b.iter()
                .zip(&centred)
                .map(|(u, c)| u * c)
                .sum::<f64>()
                .powi(2)
        })
        .sum();
    (total - captured).max(0.0)
}

/// Compresses `data` (`points × dimension` scalars, row by row) by clustered PCA.
///
/// # Panics
/// If `dimension` is 0 or does not divide `data.len()`.
#[must_use]
pub fn cpca(data: &[f32], dimension: usize, opt: &CpcaOptions) -> Cpca {
    let fit = cpca_fit(data, dimension, opt);
    let m = fit.components_for(opt);
    fit.stored(data, m)
}

/// Clusters `data` and fits every cluster's mean and full principal basis (k-means, then
/// CPCA's refinement with the `M` of `opt`): the stored form of any `M` is then a truncation
/// ([`CpcaFit::stored`]), so a caller can try several without clustering again.
///
/// # Panics
/// If `dimension` is 0 or does not divide `data.len()`.
#[must_use]
pub fn cpca_fit(data: &[f32], dimension: usize, opt: &CpcaOptions) -> CpcaFit {
    let d = dimension;
    assert!(
        d > 0 && data.len().is_multiple_of(d),
        "data of {} scalars is not rows of {d}",
        data.len()
    );
    let points = data.len() / d;
    let block = Block {
        data,
        d,
        points,
        k: opt.clusters.clamp(1, points.max(1)),
        total_energy: data.iter().map(|&v| f64::from(v).powi(2)).sum(),
    };
    let mut centres = block.kmeans_pp_start(opt.seed);
    let assign = block.kmeans(&mut centres, opt.kmeans_iterations);
    let (assign, models, _) = block.refine(assign, opt);
    CpcaFit {
        d,
        k: block.k,
        total_energy: block.total_energy,
        assign,
        models,
    }
}

/// A block's clusters and their full principal bases ([`cpca_fit`]).
pub struct CpcaFit {
    d: usize,
    k: usize,
    total_energy: f64,
    assign: Vec<usize>,
    models: Vec<Model>,
}

impl CpcaFit {
    /// The basis vectors per cluster `opt` asks for: `opt.components`, or the fewest whose
    /// discarded variance keeps the block's relative L2 error within `opt.error_target`.
    #[must_use]
    pub fn components_for(&self, opt: &CpcaOptions) -> usize {
        let block = Block {
            data: &[],
            d: self.d,
            points: self.assign.len(),
            k: self.k,
            total_energy: self.total_energy,
        };
        block.choose_m(&self.models, &self.assign, opt)
    }

    /// The stored form with `m` basis vectors per cluster (at most the dimension) of `data`,
    /// the block this was fitted to, and its measured error.
    ///
    /// # Panics
    /// If `data` is not the fitted block's size.
    #[must_use]
    pub fn stored(&self, data: &[f32], m: usize) -> Cpca {
        assert_eq!(
            data.len(),
            self.assign.len() * self.d,
            "not the fitted block"
        );
        let block = Block {
            data,
            d: self.d,
            points: self.assign.len(),
            k: self.k,
            total_energy: self.total_energy,
        };
        block.stored_form(&self.models, &self.assign, m.min(self.d))
    }
}

/// One block being compressed: `points` rows of `d` scalars, into `k` clusters.
struct Block<'a> {
    data: &'a [f32],
    d: usize,
    points: usize,
    k: usize,
    /// `Σ x²` over the block: the denominator of its relative error.
    total_energy: f64,
}

impl Block<'_> {
    /// Point `p`'s row.
    fn row(&self, p: usize) -> &[f32] {
        &self.data[p * self.d..(p + 1) * self.d]
    }

    /// The k-means++ start: the first centre at random, each next one with probability ∝ the
    /// squared distance to the nearest centre chosen so far (a PCG stream keyed by `seed`).
    fn kmeans_pp_start(&self, seed: u64) -> Vec<Vec<f64>> {
        let (points, k) = (self.points, self.k);
        let mut rng = Pcg64::seed_from_u64(seed ^ 0x00c0_ffee_c1a5_7e25);
        let mut centres: Vec<Vec<f64>> = Vec::with_capacity(k);
        if points == 0 {
            return centres;
        }
        let first = rng.random_range(0..points);
        centres.push(self.row(first).iter().map(|&v| f64::from(v)).collect());
        let mut nearest: Vec<f64> = (0..points)
            .map(|p| sq_dist(self.row(p), &centres[0]))
            .collect();
        while centres.len() < k {
            let total: f64 = nearest.iter().sum();
            let pick = if total > 0.0 {
                let mut t = rng.random::<f64>() * total;
                let mut chosen = points - 1;
                for (p, &w) in nearest.iter().enumerate() {
                    if t < w {
                        chosen = p;
                        break;
                    }
                    t -= w;
                }
                chosen
            } else {
                centres.len() % points
            };
            let c: Vec<f64> = self.row(pick).iter().map(|&v| f64::from(v)).collect();
            nearest
                .iter_mut()
                .enumerate()
                .for_each(|(p, n)| *n = n.min(sq_dist(self.row(p), &c)));
            centres.push(c);
        }
        centres
    }

    /// Lloyd iterations from `centres` (moved to their members' means) until no point changes
    /// cluster or `iterations` are done; each point's cluster.
    fn kmeans(&self, centres: &mut [Vec<f64>], iterations: usize) -> Vec<usize> {
        let points = self.points;
        let mut assign: Vec<usize> = vec![0; points];
        for _ in 0..iterations {
            let next: Vec<usize> = (0..points)
                .into_par_iter()
                .with_min_len(256)
                .map(|p| {
                    let mut best = (f64::INFINITY, 0);
                    for (c, centre) in centres.iter().enumerate() {
                        let e = sq_dist(self.row(p), centre);
                        if e < best.0 {
                            best = (e, c);
                        }
                    }
                    best.1
                })
                .collect();
            let changed = next != assign;
            assign = next;
            for (c, centre) in centres.iter_mut().enumerate() {
                let members: Vec<usize> = (0..points).filter(|&p| assign[p] == c).collect();
                if members.is_empty() {
                    continue;
                }
                centre.iter_mut().for_each(|x| *x = 0.0);
                for &p in &members {
                    for (x, &v) in centre.iter_mut().zip(self.row(p)) {
                        *x += f64::from(v);
                    }
                }
                centre.iter_mut().for_each(|x| *x /= members.len() as f64);
            }
            if !changed {
                break;
            }
        }
        assign
    }

    /// The points of each cluster, in index order.
    fn members_of(&self, assign: &[usize]) -> Vec<Vec<usize>> {
        let mut m = vec![Vec::new(); self.k];
        for (p, &c) in assign.iter().enumerate() {
            m[c].push(p);
        }
        m
    }

    /// Every cluster's model.
    fn fit_all(&self, assign: &[usize]) -> Vec<Model> {
        self.members_of(assign)
            .par_iter()
            .map(|members| fit(self.data, self.d, members))
            .collect()
    }

    /// The fewest directions whose discarded variance keeps the block within the target (or
    /// the asked number, at most `d`).
    fn choose_m(&self, models: &[Model], assign: &[usize], opt: &CpcaOptions) -> usize {
        let d = self.d;
        if let Some(m) = opt.components {
            return m.min(d);
        }
        let sizes: Vec<f64> = self
            .members_of(assign)
            .iter()
            .map(|m| m.len() as f64)
            .collect();
        let budget = opt.error_target.powi(2) * self.total_energy;
        (0..=d)
            .find(|&m| {
                let lost: f64 = models
                    .iter()
                    .zip(&sizes)
                    .map(|(model, n)| n * model.variances[m..].iter().sum::<f64>())
                    .sum();
                lost <= budget
            })
            .unwrap_or(d)
    }

    /// CPCA's refinement of the clusters `assign`: each point moves to the cluster whose mean
    /// and `m` directions reconstruct it best, and the models are refitted, until nothing
    /// moves or `opt.refinements` rounds are done; the clusters, their models and `m`.
    fn refine(&self, mut assign: Vec<usize>, opt: &CpcaOptions) -> (Vec<usize>, Vec<Model>, usize) {
        let mut models = self.fit_all(&assign);
        let mut m = self.choose_m(&models, &assign, opt);
        for _ in 0..opt.refinements {
            let next: Vec<usize> = (0..self.points)
                .into_par_iter()
                .with_min_len(256)
                .map(|p| {
                    let mut best = (f64::INFINITY, assign[p]);
                    for (c, model) in models.iter().enumerate() {
                        if model.basis.is_empty() {
                            continue;
                        }
                        let e = residual(self.row(p), model, m);
                        if e < best.0 {
                            best = (e, c);
                        }
                    }
                    best.1
                })
                .collect();
            if next == assign {
                break;
            }
            assign = next;
            models = self.fit_all(&assign);
            m = self.choose_m(&models, &assign, opt);
        }
        (assign, models, m)
    }

    /// The stored form, in f32, and its measured error.
    fn stored_form(&self, models: &[Model], assign: &[usize], m: usize) -> Cpca {
        let (k, d) = (self.k, self.d);
        let mut centres_out = Vec::with_capacity(k * (m + 1) * d);
        for model in models {
            centres_out.extend(model.mean.iter().map(|&v| v as f32));
            for b in &model.basis[..m] {
                centres_out.extend(b.iter().map(|&v| v as f32));
            }
        }
        let weights: Vec<f32> = (0..self.points)
            .into_par_iter()
            .with_min_len(256)
            .flat_map_iter(|p| {
                let model = &models[assign[p]];
                let centred: Vec<f64> = self
                    .row(p)
                    .iter()
                    .zip(&model.mean)
                    .map(|(&v, mu)| f64::from(v) - mu)
                    .collect();
                model.basis[..m]
                    .iter()
                    .map(move |b| b.iter().zip(&centred).map(|(u, c)| u * c).sum::<f64>() as f32)
                    .collect::<Vec<f32>>()
            })
            .collect();
        let mut out = Cpca {
            clusters: k as u32,
            components: m as u32,
            dimension: d as u32,
            rel_error: 0.0,
            centres: centres_out,
            cluster_of: assign.iter().map(|&c| c as u32).collect(),
            weights,
        };
        let approx = out.reconstruct();
        let err: f64 = approx
            .iter()
            .zip(self.data)
            .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
            .sum();
        out.rel_error = if self.total_energy > 0.0 {
            (err / self.total_energy).sqrt()
        } else {
            0.0
        };
        out
    }
}

/// What `prt compress` is asked: the cluster count (`None`: per object, points/256 within
/// 1..=64), the basis vectors per cluster (`None`: the fewest meeting `error_target`) and the
/// relative L2 error they aim at.
#[derive(Clone, Copy, Debug)]
pub struct CompressPolicy {
    /// Clusters per block, or per object's point count.
    pub clusters: Option<usize>,
    /// Basis vectors per cluster, or from the error target.
    pub components: Option<usize>,
    /// The relative L2 error the component count aims at, in (0, 1).
    pub error_target: f64,
}

impl CompressPolicy {
    /// The clusters of an object of `points` points: the policy's, or `points/256` within
    /// 1..=64 (a cluster of a few hundred points keeps its basis well estimated; 64 clusters
    /// keep the per-frame cluster lighting cheap).
    #[must_use]
    pub fn clusters_for(&self, points: usize) -> usize {
        self.clusters.unwrap_or((points / 256).clamp(1, 64))
    }
}

/// Why a bake cannot be compressed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CompressError {
    /// The error target is not in (0, 1).
    #[error("--error {0} must be a relative error in (0, 1)")]
    ErrorTarget(f64),
    /// Zero clusters asked.
    #[error("--clusters must be at least 1")]
    NoClusters,
    /// An intermediate file of a distributed bake.
    #[error("an intermediate pass file; compress the finished bake")]
    IntermediatePass,
    /// One shard of a sharded bake.
    #[error("shard {index} of {count}: merge the shards first, then compress")]
    Shard {
        /// The shard's index.
        index: u32,
        /// The shard count.
        count: u32,
    },
    /// Blocks that are compressed already.
    #[error("already compressed (clustered PCA blocks); compress the original bake instead")]
    AlreadyCompressed,
    /// More components than an object's scalars per point.
    #[error(
        "--components {components} exceeds the {scalars} scalars per point of object {object}"
    )]
    TooManyComponents {
        /// Components asked.
        components: usize,
        /// The object's scalars per point.
        scalars: u64,
        /// The object.
        object: String,
    },
}

impl CompressError {
    /// Whether the refusal is about the file (and a message should name it) rather than the
    /// options.
    #[must_use]
    pub fn is_about_the_file(&self) -> bool {
        matches!(
            self,
            Self::IntermediatePass | Self::Shard { .. } | Self::AlreadyCompressed
        )
    }
}

/// One compressed block: what it was and what it became (`bytes_*` the block's payload in the
/// file's scalar type before, and the `CPCA` section after).
#[derive(Clone, Debug)]
pub struct BlockCompression {
    /// The object's name.
    pub object: String,
    /// The block's kind name (SPEC §3.4).
    pub kind: &'static str,
    /// Points in the block.
    pub points: usize,
    /// Scalars per point.
    pub dimension: usize,
    /// Clusters used.
    pub clusters: u32,
    /// Basis vectors per cluster.
    pub components: u32,
    /// Relative L2 error of the reconstruction.
    pub rel_error: f64,
    /// Bytes of the block before.
    pub bytes_before: u64,
    /// Bytes of its `CPCA` section after.
    pub bytes_after: u64,
}

fn check_compressible(
    bake: &prt_bakefile::Bake,
    policy: &CompressPolicy,
) -> Result<(), CompressError> {
    let e = policy.error_target;
    if !(e.is_finite() && e > 0.0 && e < 1.0) {
        return Err(CompressError::ErrorTarget(e));
    }
    if policy.clusters == Some(0) {
        return Err(CompressError::NoClusters);
    }
    if bake.meta.pass.is_some() {
        return Err(CompressError::IntermediatePass);
    }
    if bake.meta.shard.count != 1 {
        return Err(CompressError::Shard {
            index: bake.meta.shard.index,
            count: bake.meta.shard.count,
        });
    }
    if bake
        .objects
        .iter()
        .any(|o| o.blocks.iter().any(|b| b.cpca.is_some()))
    {
        return Err(CompressError::AlreadyCompressed);
    }
    if let Some(m) = policy.components {
        if let Some(o) = bake
            .objects
            .iter()
            .find(|o| m as u64 > o.scalars_per_point())
        {
            return Err(CompressError::TooManyComponents {
                components: m,
                scalars: o.scalars_per_point(),
                object: o.name.clone(),
            });
        }
    }
    Ok(())
}

/// How many basis vectors a block keeps: a fixed count, or the fewest that bring its
/// relative L2 error (over the coefficients) within a target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Components {
    /// This many (at most the block's dimension).
    Fixed(usize),
    /// The fewest meeting this relative L2 error.
    Error(f64),
}

/// One fitted block of a bake.
struct FittedBlock {
    object: usize,
    block: usize,
    fit: CpcaFit,
}

/// Every transfer block of a bake clustered and fitted once ([`fit_bake`]), so that stored
/// forms of several sizes can be tried ([`BakeFit::apply`]) without clustering again.
pub struct BakeFit {
    blocks: Vec<FittedBlock>,
}

/// Clusters and fits every transfer block of every object of `bake` — the diffuse ones
/// (unshadowed, shadowed, interreflected) and the visibility that the glossy path reads —
/// refining the clusters with the `M` the policy's error target (or component count) asks for.
///
/// # Errors
/// [`CompressError`]: options out of range, an intermediate or shard file, a bake that is
/// compressed already, more components than an object has scalars per point.
pub fn fit_bake(
    bake: &prt_bakefile::Bake,
    policy: &CompressPolicy,
) -> Result<BakeFit, CompressError> {
    check_compressible(bake, policy)?;
    let seed = bake.meta.seed;
    let mut blocks = Vec::new();
    for (oi, o) in bake.objects.iter().enumerate() {
        let d = o.scalars_per_point() as usize;
        let points = o.points_in_file as usize;
        if points == 0 {
            continue;
        }
        for (bi, b) in o.blocks.iter().enumerate() {
            let opt = CpcaOptions {
                clusters: policy.clusters_for(points),
                components: policy.components,
                error_target: policy.error_target,
                seed: seed
                    ^ (oi as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
                    ^ u64::from(b.kind.code()).wrapping_mul(0xbf58_476d_1ce4_e5b9),
                ..CpcaOptions::default()
            };
            blocks.push(FittedBlock {
                object: oi,
                block: bi,
                fit: cpca_fit(&b.data, d, &opt),
            });
        }
    }
    Ok(BakeFit { blocks })
}

impl BakeFit {
    /// Replaces every fitted block of `bake` (the bake this was fitted to, uncompressed) by
    /// its clustered-PCA form (SPEC §3.13) with the components `diffuse` (diffuse kinds) or
    /// `visibility` ask for, keeping the reconstructed vectors as the block's data, and
    /// records the decision with `reason`. `scalar_size`: bytes per scalar of the file the
    /// bake came from (for the reported sizes).
    ///
    /// # Panics
    /// If `bake` is not the bake this was fitted to.
    pub fn apply(
        &self,
        bake: &mut prt_bakefile::Bake,
        diffuse: Components,
        visibility: Components,
        scalar_size: usize,
        reason: String,
    ) -> Vec<BlockCompression> {
        let mut rows = Vec::new();
        for fb in &self.blocks {
            let o = &mut bake.objects[fb.object];
            let d = o.scalars_per_point() as usize;
            let points = o.points_in_file as usize;
            let b = &mut o.blocks[fb.block];
            let choice = match b.kind {
                prt_bakefile::TransferKind::Visibility => visibility,
                _ => diffuse,
            };
            let m = match choice {
                Components::Fixed(m) => m.min(d),
                Components::Error(e) => fb.fit.components_for(&CpcaOptions {
                    components: None,
                    error_target: e,
                    ..CpcaOptions::default()
                }),
            };
            let c = fb.fit.stored(&b.data, m);
            rows.push(BlockCompression {
                object: o.name.clone(),
                kind: b.kind.name(),
                points,
                dimension: d,
                clusters: c.clusters,
                components: c.components,
                rel_error: c.rel_error,
                bytes_before: (b.data.len() * scalar_size) as u64,
                bytes_after: 32
                    + 4 * (c.centres.len() + c.cluster_of.len() + c.weights.len()) as u64,
            });
            b.data = c.reconstruct();
            b.cpca = Some(c);
        }
        bake.meta.decisions.push(prt_bakefile::Decision {
            object: None,
            decision: "clustered PCA compression of every transfer block (diffuse and the glossy path's visibility)".into(),
            reason,
        });
        rows
    }
}

/// `prt compress` to a coefficient error: replaces every transfer block of every object of
/// `bake` — diffuse (unshadowed, shadowed, interreflected) and visibility, which the glossy
/// path reads — by its clustered-PCA form (SPEC §3.13) with the policy's components (or the
/// fewest meeting its relative L2 error), keeping the reconstructed vectors as the block's
/// data. Records the decision in the bake. `scalar_size`: bytes per scalar of the file the
/// bake came from (for the reported sizes). (`prt compress` aims at the relit image when it
/// has the scene: it tries the stored forms of one [`fit_bake`] with [`BakeFit::apply`].)
///
/// # Errors
/// [`CompressError`]: options out of range, an intermediate or shard file, a bake that is
/// compressed already, more components than an object has scalars per point.
pub fn compress_bake(
    bake: &mut prt_bakefile::Bake,
    policy: &CompressPolicy,
    scalar_size: usize,
) -> Result<Vec<BlockCompression>, CompressError> {
    let fit = fit_bake(bake, policy)?;
    let choice = policy
        .components
        .map_or(Components::Error(policy.error_target), Components::Fixed);
    Ok(fit.apply(bake, choice, choice, scalar_size, policy.describe()))
}

impl CompressPolicy {
    /// The policy as a decision's reason.
    #[must_use]
    pub fn describe(&self) -> String {
        format!(
            "prt compress: clusters {}, components {}, error target {} (relative L2 of the coefficients)",
            self.clusters
                .map_or("per object (points/256, 1..64)".into(), |k| k.to_string()),
            self.components
                .map_or("from the error target".into(), |m| m.to_string()),
            self.error_target
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_cluster_count_follows_the_points() {
        let policy = CompressPolicy {
            clusters: None,
            components: None,
            error_target: 0.01,
        };
        assert_eq!(policy.clusters_for(10), 1);
        assert_eq!(policy.clusters_for(256 * 7 + 255), 7);
        assert_eq!(policy.clusters_for(1 << 20), 64);
        let fixed = CompressPolicy {
            clusters: Some(3),
            ..policy
        };
        assert_eq!(fixed.clusters_for(1 << 20), 3);
    }

    #[test]
    fn refusals_about_the_file_are_told_from_bad_options() {
        assert!(CompressError::AlreadyCompressed.is_about_the_file());
        assert!(CompressError::Shard { index: 1, count: 4 }.is_about_the_file());
        assert!(!CompressError::NoClusters.is_about_the_file());
        assert!(!CompressError::ErrorTarget(2.0).is_about_the_file());
    }

    /// Points that lie exactly in `k` clusters, each an affine subspace of dimension `m`.
    fn planted(k: usize, m: usize, d: usize, per: usize, seed: u64) -> Vec<f32> {
        let mut r = Pcg64::seed_from_u64(seed);
        let mut data = Vec::new();
        for _ in 0..k {
            let mean: Vec<f32> = (0..d).map(|_| r.random_range(-5.0f32..5.0)).collect();
            let dirs: Vec<Vec<f32>> = (0..m)
                .map(|_| (0..d).map(|_| r.random_range(-1.0f32..1.0)).collect())
                .collect();
            for _ in 0..per {
                let w: Vec<f32> = (0..m).map(|_| r.random_range(-1.0f32..1.0)).collect();
                data.extend(
                    (0..d).map(|i| mean[i] + (0..m).map(|j| w[j] * dirs[j][i]).sum::<f32>()),
                );
            }
        }
        data
    }

    #[test]
    fn planted_clusters_and_subspaces_are_recovered() {
        // 4 well separated clusters, each a 3-dimensional affine subspace of R^16: with K = 4
        // and M = 3 the approximation is exact up to f32 rounding (relative ~1e-7).
        let data = planted(4, 3, 16, 60, 1);
        let c = cpca(
            &data,
            16,
            &CpcaOptions {
                clusters: 4,
                components: Some(3),
                ..CpcaOptions::default()
            },
        );
        assert!(c.rel_error < 1e-5, "rel error {}", c.rel_error);
        // Fewer directions than the subspaces have lose something.
        let c2 = cpca(
            &data,
            16,
            &CpcaOptions {
                clusters: 4,
                components: Some(2),
                ..CpcaOptions::default()
            },
        );
        assert!(c2.rel_error > 1e-3, "rel error {}", c2.rel_error);
        // The automatic choice finds M = 3 for a 1e-4 target.
        let c3 = cpca(
            &data,
            16,
            &CpcaOptions {
                clusters: 4,
                components: None,
                error_target: 1e-4,
                ..CpcaOptions::default()
            },
        );
        assert_eq!(c3.components, 3);
    }

    #[test]
    fn error_falls_with_components_and_meets_its_target() {
        let mut r = Pcg64::seed_from_u64(3);
        let data: Vec<f32> = (0..300 * 9)
            .map(|i| ((i % 9) as f32 * 0.3).sin() + r.random_range(-0.2f32..0.2))
            .collect();
        let mut last = f64::INFINITY;
        for m in 0..=9 {
            let c = cpca(
                &data,
                9,
                &CpcaOptions {
                    clusters: 3,
                    components: Some(m),
                    ..CpcaOptions::default()
                },
            );
            assert!(
                c.rel_error <= last + 1e-9,
                "M = {m}: {} after {last}",
                c.rel_error
            );
            last = c.rel_error;
        }
        assert!(last < 1e-5, "all directions: {last}");
        for target in [0.2, 0.05, 0.01] {
            let c = cpca(
                &data,
                9,
                &CpcaOptions {
                    clusters: 3,
                    error_target: target,
                    ..CpcaOptions::default()
                },
            );
            // The choice is made on the f64 model; the stored f32 form adds ~1e-7.
            assert!(
                c.rel_error <= target + 1e-6,
                "target {target}: {}",
                c.rel_error
            );
        }
    }

    #[test]
    fn one_fit_serves_every_stored_size() {
        // Truncating one fit's bases: the error falls with M, the size the error target asks
        // for meets it, and M = D is exact (up to f32 rounding, relative ~1e-7).
        let data = planted(3, 4, 10, 80, 5);
        let fit = cpca_fit(
            &data,
            10,
            &CpcaOptions {
                clusters: 3,
                components: Some(2),
                ..CpcaOptions::default()
            },
        );
        let mut last = f64::INFINITY;
        for m in 0..=10 {
            let c = fit.stored(&data, m);
            assert_eq!(c.components as usize, m);
            assert!(c.rel_error <= last + 1e-9, "M = {m}: {}", c.rel_error);
            last = c.rel_error;
        }
        assert!(last < 1e-5, "{last}");
        for e in [0.3, 0.1, 0.01] {
            let m = fit.components_for(&CpcaOptions {
                error_target: e,
                ..CpcaOptions::default()
            });
            let c = fit.stored(&data, m);
            // Chosen on the f64 model; the stored f32 form adds ~1e-7.
            assert!(
                c.rel_error <= e + 1e-6,
                "target {e}: M = {m}, {}",
                c.rel_error
            );
        }
    }

    #[test]
    fn same_result_on_any_thread_count() {
        let data = planted(5, 2, 12, 200, 9);
        let opt = CpcaOptions {
            clusters: 6,
            components: Some(2),
            ..CpcaOptions::default()
        };
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| cpca(&data, 12, &opt));
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
            .install(|| cpca(&data, 12, &opt));
        assert_eq!(one, two);
    }
}

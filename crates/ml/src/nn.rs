//! A compact dense neural network for the fault classifiers: f64, softmax + cross-entropy,
//! Adam, mini-batches, early stopping on a validation split. Deterministic: the same seed gives
//! the same model bit for bit (single-threaded, fixed iteration order).
//!
//! The backward pass is checked against finite differences in the tests.

/// Hidden-layer activation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Activation {
    /// Logistic sigmoid (the paper's networks).
    Sigmoid,
    /// max(0, x) (this project's network: exact in integer arithmetic after quantization).
    Relu,
}

impl Activation {
    fn apply(self, x: f64) -> f64 {
        match self {
            Self::Sigmoid => 1.0 / (1.0 + (-x).exp()),
            Self::Relu => x.max(0.0),
        }
    }
    /// Derivative expressed through the activation's output `y`.
    fn grad_from_output(self, y: f64) -> f64 {
        match self {
            Self::Sigmoid => y * (1.0 - y),
            Self::Relu => {
                if y > 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }
    /// Stable name used in model files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Sigmoid => "sigmoid",
            Self::Relu => "relu",
        }
    }
    /// Parses [`Activation::name`].
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "sigmoid" => Some(Self::Sigmoid),
            "relu" => Some(Self::Relu),
            _ => None,
        }
    }
}

/// SplitMix64: a tiny deterministic generator for initialisation and shuffling.
#[derive(Debug, Clone)]
pub struct SplitMix(u64);

impl SplitMix {
    /// Generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal draw (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(f64::MIN_POSITIVE);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
    /// Fisher–Yates shuffle.
    pub fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            let j = (self.next_u64() % (i as u64 + 1)) as usize;
            v.swap(i, j);
        }
    }
}

/// One dense layer: `y = W x + b`, `W` row-major `n_out × n_in`.
#[derive(Debug, Clone, PartialEq)]
pub struct Dense {
    /// Inputs.
    pub n_in: usize,
    /// Outputs.
    pub n_out: usize,
    /// Weights, row `o` holds the weights of output `o`.
    pub w: Vec<f64>,
    /// Biases.
    pub b: Vec<f64>,
}

/// A multilayer perceptron with input standardisation and a softmax output.
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    /// Per-input mean subtracted before the first layer (from the training split).
    pub in_mean: Vec<f64>,
    /// Per-input standard deviation divided out before the first layer.
    pub in_std: Vec<f64>,
    /// Layers; every layer but the last is followed by `activation`.
    pub layers: Vec<Dense>,
    /// Hidden activation.
    pub activation: Activation,
}

impl Mlp {
    /// A network with layer widths `sizes` (`[inputs, hidden…, classes]`), Glorot-uniform
    /// weights and zero biases, identity standardisation.
    pub fn new(sizes: &[usize], activation: Activation, seed: u64) -> Self {
        let mut rng = SplitMix::new(seed);
        let layers = sizes
            .windows(2)
            .map(|w| {
                let (n_in, n_out) = (w[0], w[1]);
                let limit = (6.0 / (n_in + n_out) as f64).sqrt();
                Dense {
                    n_in,
                    n_out,
                    w: (0..n_in * n_out).map(|_| (2.0 * rng.uniform() - 1.0) * limit).collect(),
                    b: vec![0.0; n_out],
                }
            })
            .collect();
        let n = sizes.first().copied().unwrap_or(0);
        Self { in_mean: vec![0.0; n], in_std: vec![1.0; n], layers, activation }
    }

    /// Number of inputs.
    pub fn n_inputs(&self) -> usize {
        self.in_mean.len()
    }

    /// Number of classes.
    pub fn n_classes(&self) -> usize {
        self.layers.last().map_or(0, |l| l.n_out)
    }

    /// Standardised input.
    pub fn standardise(&self, x: &[f64]) -> Vec<f64> {
        x.iter().zip(&self.in_mean).zip(&self.in_std).map(|((v, m), s)| (v - m) / s).collect()
    }

    /// Activations of every layer for a standardised input (last = logits).
    fn forward_all(&self, z: &[f64]) -> Vec<Vec<f64>> {
        let mut acts = Vec::with_capacity(self.layers.len() + 1);
        acts.push(z.to_vec());
        for (li, l) in self.layers.iter().enumerate() {
            let x = &acts[li];
            let last = li + 1 == self.layers.len();
            let y: Vec<f64> = (0..l.n_out)
                .map(|o| {
                    let row = &l.w[o * l.n_in..(o + 1) * l.n_in];
                    let s = l.b[o] + row.iter().zip(x).map(|(w, v)| w * v).sum::<f64>();
                    if last {
                        s
                    } else {
                        self.activation.apply(s)
                    }
                })
                .collect();
            acts.push(y);
        }
        acts
    }

    /// Logits of a raw (unstandardised) input.
    pub fn logits(&self, x: &[f64]) -> Vec<f64> {
        self.forward_all(&self.standardise(x)).pop().unwrap_or_default()
    }

    /// Softmax probabilities of a raw input.
    pub fn probabilities(&self, x: &[f64]) -> Vec<f64> {
        softmax(&self.logits(x))
    }

    /// Most likely class of a raw input.
    pub fn predict(&self, x: &[f64]) -> usize {
        argmax(&self.logits(x))
    }

    /// Mean cross-entropy over standardised inputs; adds its gradient into `grad` (same shape
    /// as the layers) when given.
    fn loss(&self, zs: &[&[f64]], ys: &[usize], mut grad: Option<&mut [Dense]>) -> f64 {
        let inv_n = 1.0 / zs.len().max(1) as f64;
        let mut total = 0.0;
        for (z, &y) in zs.iter().zip(ys) {
            let acts = self.forward_all(z);
            let p = softmax(acts.last().map_or(&[][..], |v| v));
            total -= p.get(y).copied().unwrap_or(1.0).max(1e-300).ln();
            let Some(g) = grad.as_deref_mut() else { continue };
            // dL/dlogits = p - onehot(y)
            let mut delta: Vec<f64> = p.iter().enumerate().map(|(i, &pi)| (pi - f64::from(i == y)) * inv_n).collect();
            for li in (0..self.layers.len()).rev() {
                let l = &self.layers[li];
                let x = &acts[li];
                let gl = &mut g[li];
                for (o, &d) in delta.iter().enumerate() {
                    gl.b[o] += d;
                    let row = &mut gl.w[o * l.n_in..(o + 1) * l.n_in];
                    for (gw, xv) in row.iter_mut().zip(x) {
                        *gw += d * xv;
                    }
                }
                if li > 0 {
                    delta = (0..l.n_in)
                        .map(|i| {
                            let s: f64 = (0..l.n_out).map(|o| l.w[o * l.n_in + i] * delta[o]).sum();
                            s * self.activation.grad_from_output(x[i])
                        })
                        .collect();
                }
            }
        }
        total * inv_n
    }

    fn zero_like(&self) -> Vec<Dense> {
        self.layers.iter().map(|l| Dense { w: vec![0.0; l.w.len()], b: vec![0.0; l.b.len()], ..*l }).collect()
    }
}

/// Softmax of logits (max-shifted).
pub fn softmax(logits: &[f64]) -> Vec<f64> {
    let m = logits.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = logits.iter().map(|l| (l - m).exp()).collect();
    let s: f64 = e.iter().sum();
    e.iter().map(|v| v / s).collect()
}

/// Index of the largest value (first on ties).
pub fn argmax(v: &[f64]) -> usize {
    let mut best = 0;
    for (i, x) in v.iter().enumerate() {
        if *x > v[best] {
            best = i;
        }
    }
    best
}

/// Training settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainConfig {
    /// Hidden layer widths.
    pub hidden: [usize; 2],
    /// Hidden activation.
    pub activation: Activation,
    /// Adam learning rate.
    pub learning_rate: f64,
    /// Mini-batch size.
    pub batch: usize,
    /// Upper bound on epochs.
    pub max_epochs: usize,
    /// Early stopping: epochs without a better validation loss before stopping.
    pub patience: usize,
    /// Fraction of the training data held out for validation.
    pub validation_fraction: f64,
    /// Decoupled weight decay per step, as a fraction of the learning rate (AdamW); 0 = none.
    pub weight_decay: f64,
    /// σ of Gaussian noise added to every standardised input of a training batch; 0 = none.
    pub input_noise: f64,
    /// Networks trained from different initialisations by [`train_best_of`]; the one with the
    /// lowest validation loss is kept (1 = just the seed's).
    pub candidates: usize,
    /// Seed of initialisation, split and shuffling.
    pub seed: u64,
}

impl TrainConfig {
    /// The paper's protocol (SPEC §6): 8 × 8 sigmoid, Adam 1e-3, patience 3, 80/20 split,
    /// Keras' default batch of 32.
    pub fn paper(seed: u64) -> Self {
        Self {
            hidden: [8, 8],
            activation: Activation::Sigmoid,
            learning_rate: 1e-3,
            batch: 32,
            max_epochs: 500,
            patience: 3,
            validation_fraction: 0.2,
            weight_decay: 0.0,
            input_noise: 0.0,
            candidates: 1,
            seed,
        }
    }
}

/// What happened during training.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainLog {
    /// Epochs run.
    pub epochs: usize,
    /// Epoch (1-based) whose weights were kept.
    pub best_epoch: usize,
    /// Validation loss of the kept weights.
    pub best_val_loss: f64,
    /// Validation accuracy of the kept weights.
    pub val_accuracy: f64,
}

/// Trains a classifier on rows `x` (raw features) with labels `y` in `0..n_classes`. Inputs are
/// standardised with the mean/std of the training split; the weights of the epoch with the
/// lowest validation loss are kept (Keras `restore_best_weights`).
pub fn train(x: &[Vec<f64>], y: &[usize], groups: &[usize], n_classes: usize, cfg: &TrainConfig) -> (Mlp, TrainLog) {
    train_with_init(x, y, groups, n_classes, cfg, cfg.seed)
}

/// [`train`] with the validation split drawn from `cfg.seed` and the initialisation, shuffling
/// and noise from `init`.
fn train_with_init(
    x: &[Vec<f64>],
    y: &[usize],
    groups: &[usize],
    n_classes: usize,
    cfg: &TrainConfig,
    init: u64,
) -> (Mlp, TrainLog) {
    let n_in = x.first().map_or(0, Vec::len);
    let mut rng = SplitMix::new(cfg.seed ^ 0x5eed);
    // Validation holds out whole groups (e.g. every snapshot of one release): rows of one
    // release are near-copies of each other, and a validation split that shares releases with
    // the training split rewards memorising them, so early stopping would stop on the wrong epoch.
    let mut group_ids: Vec<usize> = groups.to_vec();
    group_ids.sort_unstable();
    group_ids.dedup();
    rng.shuffle(&mut group_ids);
    let n_val_groups = ((group_ids.len() as f64) * cfg.validation_fraction).round() as usize;
    let val_groups: std::collections::HashSet<usize> = group_ids.iter().take(n_val_groups).copied().collect();
    let (val_idx, train_idx): (Vec<usize>, Vec<usize>) =
        (0..x.len()).partition(|&i| groups.get(i).is_some_and(|g| val_groups.contains(g)));
    let mut noise_rng = SplitMix::new(init ^ 0x0015_e000);
    if init != cfg.seed {
        rng = SplitMix::new(init ^ 0x5eed);
    }
    let mut net = Mlp::new(&[n_in, cfg.hidden[0], cfg.hidden[1], n_classes], cfg.activation, init);
    // Standardisation from the training split only.
    let n = train_idx.len().max(1) as f64;
    for (j, (mean_j, std_j)) in net.in_mean.iter_mut().zip(net.in_std.iter_mut()).enumerate() {
        let mean = train_idx.iter().map(|&i| x[i][j]).sum::<f64>() / n;
        let var = train_idx.iter().map(|&i| (x[i][j] - mean).powi(2)).sum::<f64>() / n;
        *mean_j = mean;
        *std_j = if var > 1e-24 { var.sqrt() } else { 1.0 };
    }
    let z: Vec<Vec<f64>> = x.iter().map(|r| net.standardise(r)).collect();
    let val_z: Vec<&[f64]> = val_idx.iter().map(|&i| z[i].as_slice()).collect();
    let val_y: Vec<usize> = val_idx.iter().map(|&i| y[i]).collect();
    let mut adam = Adam::new(&net, cfg.learning_rate);
    let mut best = (f64::INFINITY, net.clone(), 0usize);
    let mut train_order = train_idx.clone();
    let mut epochs = 0;
    for epoch in 1..=cfg.max_epochs {
        epochs = epoch;
        rng.shuffle(&mut train_order);
        for chunk in train_order.chunks(cfg.batch.max(1)) {
            let noisy: Vec<Vec<f64>> = if cfg.input_noise > 0.0 {
                chunk.iter().map(|&i| z[i].iter().map(|v| v + cfg.input_noise * noise_rng.normal()).collect()).collect()
            } else {
                Vec::new()
            };
            let bz: Vec<&[f64]> = if noisy.is_empty() {
                chunk.iter().map(|&i| z[i].as_slice()).collect()
            } else {
                noisy.iter().map(Vec::as_slice).collect()
            };
            let by: Vec<usize> = chunk.iter().map(|&i| y[i]).collect();
            let mut g = net.zero_like();
            net.loss(&bz, &by, Some(&mut g));
            adam.step(&mut net, &g);
            if cfg.weight_decay > 0.0 {
                let keep = 1.0 - cfg.learning_rate * cfg.weight_decay;
                net.layers.iter_mut().flat_map(|l| l.w.iter_mut()).for_each(|w| *w *= keep);
            }
        }
        let val_loss = if val_z.is_empty() { 0.0 } else { net.loss(&val_z, &val_y, None) };
        if val_loss < best.0 {
            best = (val_loss, net.clone(), epoch);
        } else if epoch - best.2 >= cfg.patience {
            break;
        }
    }
    let (best_val_loss, net, best_epoch) = best;
    let correct = val_z.iter().zip(&val_y).filter(|(z, &y)| argmax(&net.forward_all(z)[net.layers.len()]) == y).count();
    let val_accuracy = correct as f64 / val_z.len().max(1) as f64;
    (net, TrainLog { epochs, best_epoch, best_val_loss, val_accuracy })
}

/// Trains `cfg.candidates` networks ([`train`]; the first with `cfg.seed`, the others with
/// seeds derived from it, all with the same validation split) and keeps the one with the lowest
/// validation loss: one unlucky initialisation no longer decides the model.
pub fn train_best_of(
    x: &[Vec<f64>],
    y: &[usize],
    groups: &[usize],
    n_classes: usize,
    cfg: &TrainConfig,
) -> (Mlp, TrainLog) {
    let mut best: Option<(Mlp, TrainLog)> = None;
    for i in 0..cfg.candidates.max(1) as u64 {
        let init = cfg.seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let (net, log) = train_with_init(x, y, groups, n_classes, cfg, init);
        if best.as_ref().is_none_or(|b| log.best_val_loss < b.1.best_val_loss) {
            best = Some((net, log));
        }
    }
    best.unwrap_or_else(|| train(x, y, groups, n_classes, cfg))
}

/// Adam optimiser state (Kingma & Ba; β1 0.9, β2 0.999, ε 1e-7 as in Keras).
struct Adam {
    lr: f64,
    t: i32,
    m: Vec<Dense>,
    v: Vec<Dense>,
}

impl Adam {
    fn new(net: &Mlp, lr: f64) -> Self {
        Self { lr, t: 0, m: net.zero_like(), v: net.zero_like() }
    }

    fn step(&mut self, net: &mut Mlp, g: &[Dense]) {
        const B1: f64 = 0.9;
        const B2: f64 = 0.999;
        const EPS: f64 = 1e-7;
        self.t += 1;
        let c1 = 1.0 - B1.powi(self.t);
        let c2 = 1.0 - B2.powi(self.t);
        let lr = self.lr;
        let update = |p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64]| {
            for i in 0..p.len() {
                m[i] = B1 * m[i] + (1.0 - B1) * g[i];
                v[i] = B2 * v[i] + (1.0 - B2) * g[i] * g[i];
                p[i] -= lr * (m[i] / c1) / ((v[i] / c2).sqrt() + EPS);
            }
        };
        for (li, l) in net.layers.iter_mut().enumerate() {
            update(&mut l.w, &g[li].w, &mut self.m[li].w, &mut self.v[li].w);
            update(&mut l.b, &g[li].b, &mut self.m[li].b, &mut self.v[li].b);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backprop_matches_finite_differences() {
        for act in [Activation::Sigmoid, Activation::Relu] {
            let net = Mlp::new(&[4, 5, 3, 3], act, 7);
            let mut rng = SplitMix::new(1);
            let xs: Vec<Vec<f64>> = (0..6).map(|_| (0..4).map(|_| 2.0 * rng.uniform() - 1.0).collect()).collect();
            let ys = [0, 1, 2, 1, 0, 2];
            let zs: Vec<&[f64]> = xs.iter().map(Vec::as_slice).collect();
            let mut g = net.zero_like();
            net.loss(&zs, &ys, Some(&mut g));
            let h = 1e-6;
            for (li, gl) in g.iter().enumerate() {
                for k in 0..net.layers[li].w.len() + net.layers[li].b.len() {
                    let mut plus = net.clone();
                    let mut minus = net.clone();
                    let (analytic, pp, pm) = if k < net.layers[li].w.len() {
                        (gl.w[k], &mut plus.layers[li].w[k], &mut minus.layers[li].w[k])
                    } else {
                        let kb = k - net.layers[li].w.len();
                        (gl.b[kb], &mut plus.layers[li].b[kb], &mut minus.layers[li].b[kb])
                    };
                    *pp += h;
                    *pm -= h;
                    let numeric = (plus.loss(&zs, &ys, None) - minus.loss(&zs, &ys, None)) / (2.0 * h);
                    assert!(
                        (numeric - analytic).abs() < 1e-6 * (1.0 + numeric.abs()),
                        "{act:?} layer {li} param {k}: numeric {numeric} analytic {analytic}"
                    );
                }
            }
        }
    }

    #[test]
    fn learns_a_separable_problem_deterministically() {
        let mut rng = SplitMix::new(3);
        let mut x = Vec::new();
        let mut y = Vec::new();
        for _ in 0..600 {
            let a = 4.0 * rng.uniform() - 2.0;
            let b = 4.0 * rng.uniform() - 2.0;
            x.push(vec![100.0 + 50.0 * a, b]); // unscaled column: standardisation must handle it
            y.push(usize::from(a + b > 0.0) + usize::from(a - b > 1.0));
        }
        let cfg = TrainConfig { learning_rate: 1e-2, ..TrainConfig::paper(11) };
        let (net, log) = train(&x, &y, &(0..x.len()).collect::<Vec<_>>(), 3, &cfg);
        assert!(log.val_accuracy > 0.9, "{log:?}");
        let (net2, log2) = train(&x, &y, &(0..x.len()).collect::<Vec<_>>(), 3, &cfg);
        assert_eq!(net, net2, "same seed, same model");
        assert_eq!(log, log2);
        let p = net.probabilities(&x[0]);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }
}

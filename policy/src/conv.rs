//! The backbone's convolutions on the CPU, forward and backward, registered with burn:
//! what training spends most of its time in.
//!
//! burn 0.22's `flex` backend re-lays every convolution's input and weights on each
//! call, and it leaves the backward pass to burn's generic rules: the weight gradient
//! becomes a convolution with batch and channels swapped (for `layer1`, one product
//! per input channel of shape 32 x 46,080 x 9) and the input gradient a transposed
//! convolution that zeroes a column buffer per sample (read in burn-flex 0.22.1's
//! source; `docs/training.md` has the profile). The arithmetic is the `kernels`
//! crate's (`kernels::conv::nchw`: im2col and one fixed-order product per group of
//! samples, the same bits for any thread count and x86-64 CPU); this module is its
//! binding to burn's tensors and autodiff, and its tests against burn's own
//! convolutions.
//!
//! burn sees two custom operations, [`ConvOps::im2col_conv2d`] and
//! [`ConvOps::im2col_conv_transpose2d`] (the decoder's upsampling: the same kernels the
//! other way round), registered through its backend extension for `Flex` and
//! `Autodiff<Flex>` (the latter with the backward pass below). [`conv2d`] and
//! [`conv_transpose2d`] are what the model calls: they take this path for a tensor on
//! the CPU, add a bias after it, and call burn's own `forward` everywhere else (the GPU
//! backends, grouped or dilated convolutions).

use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::flex::FlexTensor;
use burn::backend::tensor::FloatTensor;
use burn::backend::{Autodiff, Backend, Dispatch, DispatchDevice, Flex, backend_extension};
use burn::nn::PaddingConfig2d;
use burn::nn::conv::{Conv2d, ConvTranspose2d};
use burn::prelude::*;
use burn::tensor::{DType, TensorData};
pub use kernels::conv::nchw::{Geometry, backward, forward, input_grad, weight_grad};

/// Two custom operations for burn, without bias, groups or dilation.
#[backend_extension(Autodiff, Flex)]
pub trait ConvOps: Backend {
    /// `x [batch, cin, h, w]` convolved with `weight [cout, cin, kh, kw]` at `stride`
    /// (rows, columns) with `pad` zeros on each side (rows, columns).
    fn im2col_conv2d(
        x: FloatTensor<Self>,
        weight: FloatTensor<Self>,
        stride: [usize; 2],
        pad: [usize; 2],
    ) -> FloatTensor<Self>;

    /// The transposed convolution of `x [batch, cin, h, w]` with
    /// `weight [cin, cout, kh, kw]` (burn's and PyTorch's layout), `stride`, `pad` and
    /// `pad_out` extra rows and columns at the end: the adjoint of
    /// [`ConvOps::im2col_conv2d`], `[batch, cout, (h - 1) * stride - 2 * pad + kh + pad_out, ...]`.
    fn im2col_conv_transpose2d(
        x: FloatTensor<Self>,
        weight: FloatTensor<Self>,
        stride: [usize; 2],
        pad: [usize; 2],
        pad_out: [usize; 2],
    ) -> FloatTensor<Self>;
}

pub(crate) fn dims4(t: &FlexTensor) -> [usize; 4] {
    t.layout().shape().dims::<4>()
}

/// A contiguous f32 copy-or-view of a CPU tensor, for [`f32s`].
pub(crate) fn contiguous(t: &FlexTensor) -> FlexTensor {
    assert_eq!(
        t.dtype(),
        DType::F32,
        "the CPU convolution takes f32 tensors"
    );
    t.to_contiguous()
}

pub(crate) fn f32s(t: &FlexTensor) -> &[f32] {
    t.as_slice::<f32>().expect("a contiguous f32 tensor")
}

/// A CPU tensor of `values` in the shape `dims`.
pub(crate) fn flex(values: Vec<f32>, dims: impl Into<burn::tensor::Shape>) -> FlexTensor {
    FlexTensor::from_data(TensorData::new(values, dims))
}

/// The convolution `x * w` as a [`Geometry`].
fn conv_geometry(x: [usize; 4], w: [usize; 4], stride: [usize; 2], pad: [usize; 2]) -> Geometry {
    Geometry::new(x, w, stride, pad).unwrap_or_else(|| {
        panic!("conv2d: input {x:?} and weights {w:?} do not fit (stride {stride:?}, pad {pad:?})")
    })
}

/// The convolution whose adjoint is the transposed convolution of `x [batch, cin, h, w]`
/// with `w [cin, cout, kh, kw]`: it maps `[batch, cout, H, W]` (the transposed
/// convolution's output) back to `[batch, cin, h, w]`.
fn transpose_geometry(
    x: [usize; 4],
    w: [usize; 4],
    stride: [usize; 2],
    pad: [usize; 2],
    pad_out: [usize; 2],
) -> Geometry {
    let [batch, cin, h, wd] = x;
    let [_, cout, kh, kw] = w;
    let size = |len: usize, s: usize, k: usize, p: usize, o: usize| {
        ((len.max(1) - 1) * s + k + o).checked_sub(2 * p)
    };
    let g = size(h, stride[0], kh, pad[0], pad_out[0])
        .zip(size(wd, stride[1], kw, pad[1], pad_out[1]))
        .and_then(|(oh, ow)| Geometry::new([batch, cout, oh, ow], w, stride, pad));
    match g {
        Some(g) if (g.oh, g.ow) == (h, wd) && g.cout == cin => g,
        _ => panic!(
            "conv_transpose2d: input {x:?} and weights {w:?} do not fit (stride {stride:?}, \
             pad {pad:?}, pad_out {pad_out:?})"
        ),
    }
}

impl ConvOps for Flex {
    fn im2col_conv2d(
        x: FlexTensor,
        weight: FlexTensor,
        stride: [usize; 2],
        pad: [usize; 2],
    ) -> FlexTensor {
        let (x, w) = (contiguous(&x), contiguous(&weight));
        let g = conv_geometry(dims4(&x), dims4(&w), stride, pad);
        flex(
            forward(f32s(&x), f32s(&w), &g),
            [g.batch, g.cout, g.oh, g.ow],
        )
    }

    fn im2col_conv_transpose2d(
        x: FlexTensor,
        weight: FlexTensor,
        stride: [usize; 2],
        pad: [usize; 2],
        pad_out: [usize; 2],
    ) -> FlexTensor {
        let (x, w) = (contiguous(&x), contiguous(&weight));
        let g = transpose_geometry(dims4(&x), dims4(&w), stride, pad, pad_out);
        flex(
            input_grad(f32s(&w), f32s(&x), &g),
            [g.batch, g.cin, g.h, g.w],
        )
    }
}

/// What a backward step keeps of its forward: the contiguous input and weights, and the
/// convolution's geometry (for a transposed convolution, that of its adjoint).
type Saved = (FlexTensor, FlexTensor, Geometry);

/// The backward step of both operations on `Autodiff<Flex>`. For a convolution,
/// `dx = input_grad(w, dy)` and `dw = weight_grad(x, dy)`; a transposed convolution keeps
/// the geometry of its adjoint convolution, so there `dx = forward(dy, w)` and
/// `dw = weight_grad(dy, x)` (input and output swap roles).
#[derive(Debug)]
struct ConvBackward {
    transposed: bool,
}

impl Backward<Flex, 2> for ConvBackward {
    type State = Saved;

    fn backward(self, ops: Ops<Self::State, 2>, grads: &mut Gradients, _: &mut Checkpointer) {
        let [node_x, node_w] = ops.parents;
        let dy = contiguous(&grads.consume::<Flex>(&ops.node));
        let (x, w, g) = ops.state;
        let (x, w, dy) = (f32s(&x), f32s(&w), f32s(&dy));
        if let Some(node) = node_x {
            let dx = if self.transposed {
                flex(forward(dy, w, &g), [g.batch, g.cout, g.oh, g.ow])
            } else {
                flex(input_grad(w, dy, &g), [g.batch, g.cin, g.h, g.w])
            };
            grads.register::<Flex>(node.id, dx);
        }
        if let Some(node) = node_w {
            let (input, grad) = if self.transposed { (dy, x) } else { (x, dy) };
            let dw = weight_grad(input, grad, &g);
            grads.register::<Flex>(node.id, flex(dw, [g.cout, g.cin, g.kh, g.kw]));
        }
    }
}

/// One operation on `Autodiff<Flex>`: `run` on the primitives, with [`ConvBackward`]
/// registered (keeping the contiguous inputs and `geometry` of them) when a gradient is
/// wanted.
fn tracked<C: CheckpointStrategy>(
    x: FloatTensor<Autodiff<Flex, C>>,
    weight: FloatTensor<Autodiff<Flex, C>>,
    transposed: bool,
    geometry: impl FnOnce(&FlexTensor, &FlexTensor) -> Geometry,
    run: impl FnOnce(FlexTensor, FlexTensor) -> FlexTensor,
) -> FloatTensor<Autodiff<Flex, C>> {
    match (ConvBackward { transposed })
        .prepare::<C>([x.node(), weight.node()])
        .compute_bound()
        .stateful()
    {
        OpsKind::Tracked(prep) => {
            let (xp, wp) = (contiguous(x.primitive()), contiguous(weight.primitive()));
            let g = geometry(&xp, &wp);
            let out = run(xp.clone(), wp.clone());
            prep.finish((xp, wp, g), out)
        }
        OpsKind::UnTracked(prep) => prep.finish(run(x.into_primitive(), weight.into_primitive())),
    }
}

impl<C: CheckpointStrategy> ConvOps for Autodiff<Flex, C> {
    fn im2col_conv2d(
        x: FloatTensor<Self>,
        weight: FloatTensor<Self>,
        stride: [usize; 2],
        pad: [usize; 2],
    ) -> FloatTensor<Self> {
        tracked::<C>(
            x,
            weight,
            false,
            |x, w| conv_geometry(dims4(x), dims4(w), stride, pad),
            |x, w| Flex::im2col_conv2d(x, w, stride, pad),
        )
    }

    fn im2col_conv_transpose2d(
        x: FloatTensor<Self>,
        weight: FloatTensor<Self>,
        stride: [usize; 2],
        pad: [usize; 2],
        pad_out: [usize; 2],
    ) -> FloatTensor<Self> {
        tracked::<C>(
            x,
            weight,
            true,
            |x, w| transpose_geometry(dims4(x), dims4(w), stride, pad, pad_out),
            |x, w| Flex::im2col_conv_transpose2d(x, w, stride, pad, pad_out),
        )
    }
}

/// Whether a tensor on `device` runs on burn's `flex` CPU backend (with or without
/// autodiff).
pub(crate) fn on_flex(device: &Device) -> bool {
    matches!(
        device.clone().inner().as_dispatch(),
        DispatchDevice::Flex(_)
    )
}

/// The stride and padding of `conv` if [`ConvOps`] computes it (no groups or dilation;
/// the same padding on opposite sides).
fn im2col_form(conv: &Conv2d) -> Option<([usize; 2], [usize; 2])> {
    let pad = match conv.padding {
        PaddingConfig2d::Valid => [0, 0],
        PaddingConfig2d::Explicit(top, left, bottom, right) if top == bottom && left == right => {
            [top, left]
        }
        _ => return None,
    };
    (conv.groups == 1 && conv.dilation == [1, 1]).then_some((conv.stride, pad))
}

/// `y + bias` with the bias broadcast over batch and pixels.
fn add_bias(y: Tensor<4>, bias: &Option<burn::module::Param<Tensor<1>>>) -> Tensor<4> {
    match bias {
        Some(b) => {
            let c = b.dims()[0];
            y + b.val().reshape([1, c, 1, 1])
        }
        None => y,
    }
}

/// `conv.forward(x)`: on the CPU through [`ConvOps`], elsewhere through burn's own
/// convolution. The two agree to rounding (tested, values and gradients).
pub fn conv2d(conv: &Conv2d, x: Tensor<4>) -> Tensor<4> {
    let Some((stride, pad)) = im2col_form(conv).filter(|_| on_flex(&x.device())) else {
        return conv.forward(x);
    };
    let y = Tensor::from_dispatch(<Dispatch as ConvOps>::im2col_conv2d(
        x.into_dispatch(),
        conv.weight.val().into_dispatch(),
        stride,
        pad,
    ));
    add_bias(y, &conv.bias)
}

/// `conv.forward(x)` for a transposed convolution: on the CPU through [`ConvOps`] (no
/// groups or dilation), elsewhere through burn's own.
pub fn conv_transpose2d(conv: &ConvTranspose2d, x: Tensor<4>) -> Tensor<4> {
    if conv.groups != 1 || conv.dilation != [1, 1] || !on_flex(&x.device()) {
        return conv.forward(x);
    }
    let y = Tensor::from_dispatch(<Dispatch as ConvOps>::im2col_conv_transpose2d(
        x.into_dispatch(),
        conv.weight.val().into_dispatch(),
        conv.stride,
        conv.padding,
        conv.padding_out,
    ));
    add_bias(y, &conv.bias)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::fused::values;
    use burn::module::Param;
    use burn::nn::conv::{Conv2dConfig, ConvTranspose2dConfig};
    use burn::tensor::Distribution;

    /// A rayon pool of `n` threads.
    pub(crate) fn pool(n: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    }

    /// Asserts `ours` equals `burn` to `tol` times the largest magnitude in `burn`.
    pub(crate) fn close(what: &str, ours: &[f32], burn: &[f32], tol: f32) {
        assert_eq!(ours.len(), burn.len(), "{what}: lengths");
        let scale = burn.iter().fold(1.0f32, |m, v| m.max(v.abs()));
        for (i, (a, b)) in ours.iter().zip(burn).enumerate() {
            assert!(
                (a - b).abs() <= tol * scale,
                "{what}[{i}]: ours {a}, burn's {b} (scale {scale})"
            );
        }
    }

    /// (batch, cin, h, w, cout, kernel, stride, pad): the backbone's kinds of convolution
    /// (7x7/2 stem, 3x3/1, 3x3/2, 1x1/2 shortcut) plus a 1x1/1, odd sizes and padding wider
    /// than the image, at sizes where the late layers' grouping (few pixels per sample) and
    /// several lanes occur.
    const CASES: [[usize; 8]; 9] = [
        [3, 3, 19, 23, 8, 7, 2, 3],
        [5, 4, 9, 12, 6, 3, 1, 1],
        [4, 6, 9, 7, 5, 3, 2, 1],
        [9, 5, 4, 3, 7, 1, 2, 0],
        [2, 5, 6, 5, 3, 1, 1, 0],
        [11, 3, 3, 2, 4, 3, 1, 1],
        [1, 2, 5, 5, 3, 5, 1, 0],
        [2, 2, 1, 1, 3, 7, 1, 3],
        [2, 2, 2, 3, 2, 5, 2, 2],
    ];

    /// Runs `f` on a copy of `x0` that requires a gradient, through the loss `sum(y * r)`
    /// with a fixed `r` (so every output's gradient differs): `y`, `dx`, `dw` and `db`.
    fn run(
        x0: &Tensor<4>,
        f: impl Fn(Tensor<4>) -> Tensor<4>,
        weight: &Param<Tensor<4>>,
        bias: &Option<Param<Tensor<1>>>,
    ) -> [Vec<f32>; 4] {
        let x = x0.clone().detach().require_grad();
        let y = f(x.clone());
        let dims = y.dims();
        let r: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|i| ((i * 7 + 3) % 11) as f32 / 5.0 - 1.0)
            .collect();
        let r = Tensor::<4>::from_data(TensorData::new(r, dims), &x0.device());
        let grads = (y.clone() * r).sum().backward();
        let dx = x.grad(&grads).expect("input gradient");
        let dw = weight.val().grad(&grads).expect("weight gradient");
        let db = bias.as_ref().map_or(vec![], |b| {
            values(b.val().grad(&grads).expect("bias gradient"))
        });
        [values(y.inner()), values(dx), values(dw), db]
    }

    fn close_all(case: &str, ours: [Vec<f32>; 4], burn: [Vec<f32>; 4]) {
        for ((name, a), b) in ["y", "dx", "dw", "db"].iter().zip(&ours).zip(&burn) {
            close(&format!("{case} {name}"), a, b, 1e-5);
        }
    }

    /// Values and all gradients against burn's own `Conv2d` on the autodiff CPU device,
    /// with and without a bias.
    #[test]
    fn values_and_gradients_match_burns_convolution() {
        let device = Device::flex().autodiff();
        assert!(
            on_flex(&device),
            "the autodiff CPU device takes the im2col path"
        );
        for (case, &[b, cin, h, w, cout, k, s, p]) in CASES.iter().enumerate() {
            let conv = Conv2dConfig::new([cin, cout], [k, k])
                .with_stride([s, s])
                .with_padding(PaddingConfig2d::Explicit(p, p, p, p))
                .with_bias(case % 2 == 1)
                .init(&device);
            assert!(im2col_form(&conv).is_some());
            let x0 = Tensor::<4>::random([b, cin, h, w], Distribution::Uniform(-1.0, 1.0), &device);
            let ours = run(&x0, |x| conv2d(&conv, x), &conv.weight, &conv.bias);
            let burn = run(&x0, |x| conv.forward(x), &conv.weight, &conv.bias);
            close_all(&format!("conv case {case}"), ours, burn);
        }
    }

    /// The same for the transposed convolution against burn's `ConvTranspose2d`: the
    /// decoder's 3x3, stride 2, padding 1, output padding 1, and other shapes.
    #[test]
    fn values_and_gradients_match_burns_transposed_convolution() {
        let device = Device::flex().autodiff();
        // (batch, cin, h, w, cout, kernel, stride, pad, pad_out)
        let cases = [
            (3, 8, 3, 4, 4, 3, 2, 1, 1),
            (2, 4, 5, 6, 3, 3, 2, 1, 0),
            (4, 3, 4, 4, 5, 3, 1, 1, 0),
            (1, 2, 3, 5, 3, 4, 2, 0, 1),
            (13, 6, 2, 3, 4, 3, 2, 1, 1),
        ];
        for (case, &(b, cin, h, w, cout, k, s, p, o)) in cases.iter().enumerate() {
            let conv = ConvTranspose2dConfig::new([cin, cout], [k, k])
                .with_stride([s, s])
                .with_padding([p, p])
                .with_padding_out([o, o])
                .with_bias(case % 2 == 0)
                .init(&device);
            let x0 = Tensor::<4>::random([b, cin, h, w], Distribution::Uniform(-1.0, 1.0), &device);
            let ours = run(
                &x0,
                |x| conv_transpose2d(&conv, x),
                &conv.weight,
                &conv.bias,
            );
            let burn = run(&x0, |x| conv.forward(x), &conv.weight, &conv.bias);
            close_all(&format!("transposed case {case}"), ours, burn);
        }
    }

    /// The kernels alone against a direct loop over the convolution's definition.
    #[test]
    fn the_kernels_compute_the_definition() {
        let noise = |len: usize, seed: usize| -> Vec<f32> {
            (0..len)
                .map(|i| (((i + seed) * 2_654_435_761) % 1000) as f32 / 500.0 - 1.0)
                .collect()
        };
        for &[b, cin, h, w, cout, k, s, p] in &CASES {
            let g = Geometry::new([b, cin, h, w], [cout, cin, k, k], [s, s], [p, p]).unwrap();
            let (x, wt, dy) = (
                noise(b * cin * h * w, 1),
                noise(cout * cin * k * k, 2),
                noise(b * cout * g.oh * g.ow, 3),
            );
            let y = forward(&x, &wt, &g);
            let (dx, dw) = backward(&x, &wt, &dy, &g, true, true);
            let (dx, dw) = (dx.unwrap(), dw.unwrap());
            let mut y_ref = vec![0.0f64; y.len()];
            let mut dx_ref = vec![0.0f64; x.len()];
            let mut dw_ref = vec![0.0f64; wt.len()];
            for n in 0..b {
                for o in 0..cout {
                    for oy in 0..g.oh {
                        for ox in 0..g.ow {
                            let yi = ((n * cout + o) * g.oh + oy) * g.ow + ox;
                            for c in 0..cin {
                                for ky in 0..k {
                                    for kx in 0..k {
                                        let iy = (oy * s + ky) as isize - p as isize;
                                        let ix = (ox * s + kx) as isize - p as isize;
                                        if iy < 0 || ix < 0 || iy >= h as isize || ix >= w as isize
                                        {
                                            continue;
                                        }
                                        let xi =
                                            ((n * cin + c) * h + iy as usize) * w + ix as usize;
                                        let wi = ((o * cin + c) * k + ky) * k + kx;
                                        y_ref[yi] += f64::from(x[xi]) * f64::from(wt[wi]);
                                        dx_ref[xi] += f64::from(dy[yi]) * f64::from(wt[wi]);
                                        dw_ref[wi] += f64::from(dy[yi]) * f64::from(x[xi]);
                                    }
                                }
                            }
                        }
                    }
                }
            }
            let f = |v: Vec<f64>| v.into_iter().map(|v| v as f32).collect::<Vec<f32>>();
            close("y", &y, &f(y_ref), 1e-5);
            close("dx", &dx, &f(dx_ref), 1e-5);
            close("dw", &dw, &f(dw_ref), 1e-5);
        }
    }

    /// One thread or two, the same bits: the groups and lanes follow the shapes only.
    #[test]
    fn results_are_bit_identical_for_any_thread_count() {
        let (b, cin, h, w, cout, k, s, p) = (13, 8, 6, 10, 16, 3, 1, 1);
        let g = Geometry::new([b, cin, h, w], [cout, cin, k, k], [s, s], [p, p]).unwrap();
        let x: Vec<f32> = (0..b * cin * h * w)
            .map(|i| ((i * 37) % 101) as f32 / 50.0 - 1.0)
            .collect();
        let wt: Vec<f32> = (0..cout * cin * k * k)
            .map(|i| ((i * 53) % 97) as f32 / 48.0 - 1.0)
            .collect();
        let dy: Vec<f32> = (0..b * cout * h * w)
            .map(|i| ((i * 29) % 89) as f32 / 44.0 - 1.0)
            .collect();
        let bits = |threads| {
            pool(threads).install(|| {
                [
                    forward(&x, &wt, &g),
                    input_grad(&wt, &dy, &g),
                    weight_grad(&x, &dy, &g),
                ]
                .map(|v| v.iter().map(|f| f.to_bits()).collect::<Vec<u32>>())
            })
        };
        assert_eq!(bits(1), bits(2));
        assert_eq!(bits(1), bits(3));
    }

    #[test]
    fn only_the_asked_gradients_are_computed() {
        let g = Geometry::new([2, 3, 5, 5], [4, 3, 3, 3], [1, 1], [1, 1]).unwrap();
        let (x, w, dy) = (vec![0.5; 150], vec![0.25; 108], vec![1.0; 200]);
        let (dx, dw) = backward(&x, &w, &dy, &g, false, true);
        assert!(dx.is_none() && dw.is_some());
        let (dx, dw) = backward(&x, &w, &dy, &g, true, false);
        assert!(dx.is_some() && dw.is_none());
    }

    #[test]
    fn shapes_that_do_not_fit_have_no_geometry() {
        // Channel counts differ; the kernel is larger than the padded input; stride 0.
        assert!(Geometry::new([1, 3, 8, 8], [4, 2, 3, 3], [1, 1], [0, 0]).is_none());
        assert!(Geometry::new([1, 3, 2, 2], [4, 3, 5, 5], [1, 1], [1, 1]).is_none());
        assert!(Geometry::new([1, 3, 8, 8], [4, 3, 3, 3], [0, 1], [0, 0]).is_none());
        let g = Geometry::new([1, 3, 8, 8], [4, 3, 3, 3], [2, 2], [1, 1]).unwrap();
        assert_eq!((g.oh, g.ow), (4, 4));
    }

    #[test]
    fn grouped_or_dilated_convolutions_go_to_burn() {
        let device = Device::flex();
        let plain = Conv2dConfig::new([4, 4], [3, 3]).with_bias(false);
        assert!(im2col_form(&plain.clone().init(&device)).is_some());
        assert!(im2col_form(&plain.clone().with_groups(2).init(&device)).is_none());
        assert!(im2col_form(&plain.clone().with_dilation([2, 2]).init(&device)).is_none());
        assert!(im2col_form(&plain.with_bias(true).init(&device)).is_some());
    }
}

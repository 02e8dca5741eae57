"""The search network's decision path: SearchNet's forward on buffers made once, in about 30
array operations of which 6 are torch matrix products, for the flight's batch-1 decisions.

Why: at batch 1 the network is ~1.3 M multiply-adds, tens of microseconds of arithmetic, but
torch's eager forward costs ~0.4-0.6 ms: module calls, convolution set-up and fresh tensors for
its 20-odd operations, and every torch call costs ~3 us of dispatch on a small CPU where a numpy
call costs ~1 us. Here every buffer is a numpy array made once per input shape, with a torch
view of it made at the same time; only the six matrix products go through torch (torch.mm
obeys torch.set_num_threads, numpy's BLAS would pick its own thread count), everything else
(copies, ReLUs, pools, the mask) is numpy writing into those buffers:
- The first convolution is linear in its input, which is the field's planes placed around the
  agent plus two offset planes that never change. Its response to the offset planes (and the
  bias) is computed once per window size; per decision only the field's planes are convolved,
  over the (h + 2) x (w + 2) cells they reach instead of the (2h - 1) x (2w - 1) window, and
  added in at the agent's offset: a third of the first layer's work, and no window to build.
- Each 3 x 3 convolution is one strided copy (im2col, through an as_strided view of a
  zero-bordered buffer) and one matrix product with the bias fused (addmm); each ReLU writes
  into the next layer's zero-bordered input.
- The local window, the four pools and the first two linear layers fill one feature vector
  that one matrix product maps (the weights of `local` and `glob` stacked).

The weights are copied when this is built, so a model trained further needs a new one
(SearchNetPolicy.reset rebuilds it when the parameters changed in place). The checkpoint, the
parameter names and SearchNet are unchanged; the logits agree with SearchNet's within float32
rounding (the sums run in another order), tested on real episodes in
tests/policy/searchnet/test_infer.py.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from numpy.lib.stride_tricks import as_strided

from .encode import OFFSET_SCALE
from .model import SearchNet

#: SearchNet.forward's value for masked moves
MASKED = -1e9


def _im2col_view(src: np.ndarray, stride: int, ho: int, wo: int) -> np.ndarray:
    """Channels-last im2col without a copy: view[b, i, j, ky, kx, c] =
    src[b, stride * i + ky, stride * j + kx, c] for a zero-bordered src (b, H, W, C)."""
    b, c = src.shape[0], src.shape[3]
    sb, sy, sx, sc = src.strides
    return as_strided(src, (b, ho, wo, 3, 3, c), (sb, stride * sy, stride * sx, sy, sx, sc), writeable=False)


def _conv_weight(weight: torch.Tensor) -> torch.Tensor:
    """(out, c, 3, 3) -> (9 c, out), rows ordered (ky, kx, c) like the im2col columns."""
    return weight.permute(2, 3, 1, 0).reshape(-1, weight.shape[0]).contiguous()


class _Conv:
    """A 3 x 3 convolution of a zero-bordered channels-last buffer (1, H, W, c): the im2col copy
    and one matrix product, (ho * wo, 9 c) @ (9 c, out) with the bias fused, into `out`."""

    def __init__(self, src: np.ndarray, stride: int, ho: int, wo: int, weight: torch.Tensor,
                 bias: torch.Tensor | None, out: np.ndarray) -> None:
        c = src.shape[3]
        self.view = _im2col_view(src, stride, ho, wo)
        self.col = np.empty((1, ho, wo, 3, 3, c), np.float32)
        self.cols = torch.from_numpy(self.col).view(ho * wo, 9 * c)
        self.weight = _conv_weight(weight)
        self.bias = bias if bias is not None else torch.zeros(weight.shape[0])
        self.out, self.t_out = out, torch.from_numpy(out)  # (ho * wo, out channels)
        self.out3 = out.reshape(ho, wo, weight.shape[0])

    def __call__(self, bias: torch.Tensor | None = None) -> np.ndarray:
        np.copyto(self.col, self.view)
        torch.addmm(self.bias if bias is None else bias, self.cols, self.weight, out=self.t_out)
        return self.out3


class _Buffers:
    """Every array one forward on an h x w field writes, made once, with torch views of them
    made at the same time. Channels-last (y, x, c): the im2col copies move runs of c floats."""

    def __init__(self, net: FastSearchNet, h: int, w: int) -> None:
        cfg = net.cfg
        cf = net.field_channels  # belief planes + on-field
        o1, o2 = cfg.conv1, cfg.conv2
        hh, ww = 2 * h - 1, 2 * w - 1  # the egocentric window
        h2, w2 = (hh - 1) // 2 + 1, (ww - 1) // 2 + 1  # after a stride-2 convolution
        h3, w3 = (h2 - 1) // 2 + 1, (w2 - 1) // 2 + 1
        self.h, self.w, self.hh, self.ww = h, w, hh, ww
        k = cfg.local // 2
        self.pad = pad = max(1, k)  # f1's zero border: 1 for conv2, k for the local window
        # the field's planes with a zero border of 2: the first layer reaches one cell past the
        # field, and that cell's 3 x 3 input one more; the on-field plane never changes
        self.field = np.zeros((1, h + 4, w + 4, cf), np.float32)
        self.field[:, 2:-2, 2:-2, cf - 1] = 1.0
        #: the belief planes' place in the field buffer, as a (1, C, h, w) view:
        #: BeliefState.planes(out=...) fills it and logits() then reads it in place
        self.planes = self.field[:, 2:-2, 2:-2, : cf - 1].transpose(0, 3, 1, 2)
        self.resp = np.empty(((h + 2) * (w + 2), o1), np.float32)
        self.conv1 = _Conv(self.field, 1, h + 2, w + 2, net.w1_field, None, self.resp)
        # the first layer's response to the offset planes plus its bias, over the window, once
        dx = (torch.arange(ww, dtype=torch.float32) - (w - 1)) / OFFSET_SCALE
        dy = (torch.arange(hh, dtype=torch.float32) - (h - 1)) / OFFSET_SCALE
        coords = torch.stack(torch.broadcast_tensors(dx[None, :], dy[:, None]))[None]
        with torch.no_grad():
            base = F.conv2d(coords, net.w1_coords, net.b1, padding=1)[0].permute(1, 2, 0).numpy()
        self.base = np.zeros((hh + 2 * pad, ww + 2 * pad, o1), np.float32)
        self.base[pad: pad + hh, pad: pad + ww] = base
        #: the base where the field's response lands, per call: the first layer's bias there
        self.patch = np.empty((h + 2, w + 2, o1), np.float32)
        self.t_patch = torch.from_numpy(self.patch).view(-1, o1)
        self.f1p = np.zeros((hh + 2 * pad, ww + 2 * pad, o1), np.float32)
        # relu(base) inside the window, 0 on the border: f1 wherever the field does not reach
        self.f1_template = np.maximum(self.base, 0.0)
        # conv2's and conv3's outputs in one (positions, channels) array: one product pools
        # the means of both
        n2, n3 = h2 * w2, h3 * w3
        self.f23 = np.empty((n2 + n3, o2), np.float32)
        self.t_f23 = torch.from_numpy(self.f23)
        self.t_f2, self.t_f3 = self.t_f23[:n2], self.t_f23[n2:]
        f2p = np.zeros((1, h2 + 2, w2 + 2, o2), np.float32)
        self.conv2 = _Conv(self.f1p[None, pad - 1: pad + hh + 1, pad - 1: pad + ww + 1], 2, h2, w2, net.w2, net.b2,
                           self.f23[:n2])
        self.conv3 = _Conv(f2p, 2, h3, w3, net.w3, net.b3, self.f23[n2:])
        self.f2_in = f2p[0, 1:-1, 1:-1]  # relu(conv2) as conv3's input
        cy, cx = hh // 2 + pad, ww // 2 + pad
        self.window = self.f1p[cy - k: cy + k + 1, cx - k: cx + k + 1]
        # the head's input [loc, max f2, max f3, mean f2, mean f3] (FastSearchNet.w_in's rows)
        nloc = o1 * cfg.local * cfg.local
        self.feat = np.empty((1, nloc + 4 * o2), np.float32)
        self.t_feat = torch.from_numpy(self.feat)
        self.loc = self.feat[0, :nloc].reshape(cfg.local, cfg.local, o1)
        self.t_max2, self.t_max3 = self.t_feat[0, nloc: nloc + o2], self.t_feat[0, nloc + o2: nloc + 2 * o2]
        self.t_means = self.t_feat[0, nloc + 2 * o2:].view(2, o2)
        self.t_mean_weights = torch.zeros((2, n2 + n3))
        self.t_mean_weights[0, :n2] = 1.0 / n2
        self.t_mean_weights[1, n2:] = 1.0 / n3
        self.t_z = torch.empty((1, cfg.hidden))
        self.t_z2 = torch.empty((1, cfg.hidden))
        self.out = np.empty((1, cfg.n_actions), np.float32)
        self.t_out = torch.from_numpy(self.out)


class FastSearchNet:
    """SearchNet's logits for one episode's belief planes at its position (batch 1, the flight),
    from buffers made once per field size.

    `logits(planes, positions, mask)` == SearchNet(egocentric(planes, positions), mask) within
    float32 rounding. Not thread-safe (the buffers are shared between calls)."""

    def __init__(self, model: SearchNet) -> None:
        cfg = model.cfg
        sd = {k: v.detach().to("cpu", torch.float32).clone() for k, v in model.state_dict().items()}
        self.cfg = cfg
        self.field_channels = cfg.field_planes + 1  # + on-field
        w1, c = sd["conv1.weight"], self.field_channels
        self.w1_field, self.w1_coords, self.b1 = w1[:, :c], w1[:, c:], sd["conv1.bias"]
        self.w2, self.b2 = sd["conv2.weight"], sd["conv2.bias"]
        self.w3, self.b3 = sd["conv3.weight"], sd["conv3.bias"]
        # local(loc) + glob(g) as one product over the feature vector: loc read channels-last,
        # (y, x, c), where SearchNet flattens (c, y, x); g = [max f2, max f3, mean f2, mean f3]
        # where SearchNet has [max f2, mean f2, max f3, mean f3]
        wl = sd["local.weight"].view(cfg.hidden, cfg.conv1, cfg.local, cfg.local).permute(0, 2, 3, 1)
        wg = sd["glob.weight"].view(cfg.hidden, 2, 2, cfg.conv2).permute(0, 2, 1, 3)
        self.w_in = torch.cat([wl.reshape(cfg.hidden, -1), wg.reshape(cfg.hidden, -1)], dim=1).T.contiguous()
        self.b_in = sd["local.bias"] + sd["glob.bias"]
        self.w_mix, self.b_mix = sd["mix.weight"].T.contiguous(), sd["mix.bias"]
        self.w_pi, self.b_pi = sd["pi.weight"].T.contiguous(), sd["pi.bias"]
        self._buffers: dict[tuple[int, int], _Buffers] = {}

    def buffers(self, h: int, w: int) -> _Buffers:
        """The buffers of an h x w field (made on first use)."""
        buf = self._buffers.get((h, w))
        if buf is None:
            buf = self._buffers[(h, w)] = _Buffers(self, h, w)
        return buf

    def input_planes(self, h: int, w: int) -> np.ndarray:
        """A (1, C, h, w) float32 view to write the belief planes into; passed back to logits,
        it is read in place (no copy)."""
        return self.buffers(h, w).planes

    def logits(self, planes: np.ndarray, positions: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
        """(1, n_actions) float32 logits (a buffer reused by the next call: copy to keep).
        planes (1, C, h, w), positions (1, 2) cells (x, y); mask: (1, A <= n_actions) bool
        valid moves, the others and actions past A get MASKED."""
        b, c, h, w = planes.shape
        if b != 1 or c + 1 != self.field_channels:
            raise ValueError(f"planes must be (1, {self.field_channels - 1}, h, w) (got {planes.shape})")
        buf = self.buffers(h, w)
        if planes is not buf.planes:
            buf.planes[:] = planes
        x, y = np.asarray(positions, dtype=np.int64).reshape(2).tolist()
        pad = buf.pad
        # the response's row j lands on window row j + h - 2 - y (its first row and column may
        # fall outside the window; the base is 0 there and they are not copied)
        r0, c0 = h - 2 - y, w - 2 - x
        np.copyto(buf.patch, buf.base[pad + r0: pad + r0 + h + 2, pad + c0: pad + c0 + w + 2])
        resp = buf.conv1(buf.t_patch)  # first layer inside the field's reach, (h + 2, w + 2, o1)
        f1p = buf.f1p
        np.copyto(f1p, buf.f1_template)  # elsewhere relu(offset response + bias)
        ra, rb, ca, cb = max(r0, 0), min(r0 + h + 2, buf.hh), max(c0, 0), min(c0 + w + 2, buf.ww)
        np.maximum(resp[ra - r0: rb - r0, ca - c0: cb - c0], 0.0, out=f1p[pad + ra: pad + rb, pad + ca: pad + cb])
        buf.loc[:] = buf.window
        buf.conv2()
        buf.t_f2.clamp_min_(0.0)
        buf.f2_in[:] = buf.conv2.out3
        buf.conv3()
        buf.t_f3.clamp_min_(0.0)
        torch.amax(buf.t_f2, dim=0, out=buf.t_max2)
        torch.amax(buf.t_f3, dim=0, out=buf.t_max3)
        torch.mm(buf.t_mean_weights, buf.t_f23, out=buf.t_means)
        z = torch.addmm(self.b_in, buf.t_feat, self.w_in, out=buf.t_z).clamp_min_(0.0)
        z2 = torch.addmm(self.b_mix, z, self.w_mix, out=buf.t_z2).clamp_min_(0.0)
        z2 += z
        torch.addmm(self.b_pi, z2, self.w_pi, out=buf.t_out)
        out = buf.out
        if mask is not None:  # (1, A) valid moves; A = 4 on static worlds: no stay
            mask = np.asarray(mask, dtype=bool)
            np.copyto(out[:, : mask.shape[1]], MASKED, where=~mask)
            out[:, mask.shape[1]:] = MASKED
        return out

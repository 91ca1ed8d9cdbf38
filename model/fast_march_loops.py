"""The compiled forward loops of the fast march (model/fast_march.py): the Euler recurrence, with
the network's layers evaluated for all aircraft of a flight at once (its adjoint sweep backward:
model/fast_march_adjoint.py).

Per-flight state is held in (lanes,) and (units, lanes) buffers so that every innermost loop
runs over aircraft on contiguous memory, and the loop bodies are branch-free so LLVM turns them
into SIMD code (the elementary functions come inlined from model/fast_march_math.py).  The
network arrives as `network(packed, theta)`'s tuple (model/fast_march_packing.py's format).
The growth law arrives as (c, m, terms): terms empty for C dK**m (Paris, Walker), else the
NASGRO terms (model.nasgro.march_terms), each law in its own lane loop so that the C dK**m loops
are the same code as before the NASGRO law.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from model.fast_march_math import (
    elu,
    paris_growth,
    tanh,
)
from model.fast_march_packing import (
    ACTIVATION_ELU,
    ACTIVATION_TANH,
    KIND_MLP,
    KIND_PHYSICS,
    KIND_RESIDUAL,
    PackedKernel,
)
from model.nasgro import growth as nasgro_growth


def network(packed: PackedKernel, theta: np.ndarray) -> tuple[Any, ...]:
    """The tuple the compiled loops read: (kind, scale, input_lo, input_span, theta (flat
    parameters,), sizes, activations, weight_offsets, bias_offsets, geometry_knots,
    geometry_slopes)."""
    return (
        packed.kind,
        packed.scale,
        packed.input_lo,
        packed.input_span,
        theta,
        packed.sizes,
        packed.activations,
        packed.weight_offsets,
        packed.bias_offsets,
        packed.geometry_knots,
        packed.geometry_slopes,
    )


@njit(cache=True, error_model="numpy")
def _mlp_forward(theta, sizes, activations, w_off, b_off, hidden):
    """Fill hidden[l + 1] (units, aircraft) from hidden[0, :2] (the scaled inputs)."""
    n = hidden.shape[2]
    for layer in range(activations.shape[0]):
        n_in, n_out = sizes[layer], sizes[layer + 1]
        act = activations[layer]
        for j in range(n_out):
            bias = theta[b_off[layer] + j]
            for i in range(n):
                hidden[layer + 1, j, i] = bias
            for k in range(n_in):
                w = theta[w_off[layer] + j * n_in + k]
                for i in range(n):
                    hidden[layer + 1, j, i] += w * hidden[layer, k, i]
            if act == ACTIVATION_TANH:
                for i in range(n):
                    hidden[layer + 1, j, i] = tanh(hidden[layer + 1, j, i])
            elif act == ACTIVATION_ELU:
                for i in range(n):
                    hidden[layer + 1, j, i] = elu(hidden[layer + 1, j, i])


@njit(cache=True, error_model="numpy")
def _geometry(scale, knots, slopes, a, geo):
    """geo[0] = F(a), geo[1] = dF/da (lanes,) from a geometry table: model.geometry's formula,
    F = scale + sum_k slope_k (clamp(a, knot_k, knot_k+1) - knot_k), in its order, so the torch
    march gets the same F; the slope counts where torch's clamp passes a gradient (ends
    included)."""
    n = a.shape[0]
    for i in range(n):
        geo[0, i] = scale
        geo[1, i] = 0.0
    for k in range(slopes.shape[0]):
        lo, hi, slope = knots[k], knots[k + 1], slopes[k]
        for i in range(n):
            geo[0, i] += slope * (min(max(a[i], lo), hi) - lo)
            geo[1, i] += slope if lo <= a[i] <= hi else 0.0


@njit(cache=True, error_model="numpy")
def stress_intensity(net, s, a, hidden, dk, geo):
    """dK (lanes,) of one flight from s, a (lanes,); leaves the network's activations in hidden
    and, with a geometry table, F and dF/da in geo (2, lanes).

    net = (kind, scale, input_lo, input_span, theta, sizes, activations, w_off, b_off, knots,
    slopes).  A constant F (no knots) keeps its own loops: they are the march's hot path.
    """
    kind, scale, lo, span, theta, sizes, activations, w_off, b_off, knots, slopes = net
    n = a.shape[0]
    tabled = knots.shape[0] > 0
    if tabled:
        _geometry(scale, knots, slopes, a, geo)
    if kind == KIND_PHYSICS:
        if tabled:
            for i in range(n):
                dk[i] = geo[0, i] * s[i] * math.sqrt(math.pi * max(a[i], 0.0))
        else:
            for i in range(n):
                dk[i] = scale * s[i] * math.sqrt(math.pi * max(a[i], 0.0))
        return
    for i in range(n):
        hidden[0, 0, i] = (s[i] - lo[0]) / span[0]
        hidden[0, 1, i] = (a[i] - lo[1]) / span[1]
    if kind == KIND_RESIDUAL:  # the correction is held at the box's edge outside it
        for i in range(n):
            hidden[0, 0, i] = min(max(hidden[0, 0, i], 0.0), 1.0)
            hidden[0, 1, i] = min(max(hidden[0, 1, i], 0.0), 1.0)
    _mlp_forward(theta, sizes, activations, w_off, b_off, hidden)
    out = activations.shape[0]
    if kind == KIND_MLP:
        for i in range(n):
            dk[i] = scale * hidden[out, 0, i]
    elif tabled:
        for i in range(n):
            physics = geo[0, i] * s[i] * math.sqrt(math.pi * max(a[i], 0.0))
            dk[i] = physics * (1.0 + hidden[out, 0, i])
    else:
        for i in range(n):
            physics = scale * s[i] * math.sqrt(math.pi * max(a[i], 0.0))
            dk[i] = physics * (1.0 + hidden[out, 0, i])


@njit(cache=True, error_model="numpy")
def buffers(sizes, lanes):
    """Per-step scratch: network activations (layers + 1, widest layer, lanes), dK (lanes,) and
    a geometry table's F and dF/da (2, lanes)."""
    width = 2
    for k in range(sizes.shape[0]):
        width = max(width, sizes[k])
    return np.zeros((sizes.shape[0], width, lanes)), np.zeros(lanes), np.zeros((2, lanes))


@njit(cache=True, error_model="numpy", nogil=True)
def march_forward(stress, lengths, initial, factor, lanes, net, c, m, terms, held):
    """Trajectory (aircraft, flights + 1) of the Euler recurrence; stress is (aircraft, flights),
    factor (lanes,) the growth factor of each lane; cracks are held at `held` (m).

    The state lives in contiguous (lanes,) buffers, lanes >= aircraft; the extra lanes carry
    zero stress and are never flown.  Moving one column in and out per flight costs far less than
    transposing the (aircraft, flights) arrays.
    """
    n, steps = stress.shape
    traj = np.empty((n, steps + 1))
    hidden, dk, geo = buffers(net[5], lanes)
    a, s = np.zeros(lanes), np.zeros(lanes)
    flown = np.zeros(lanes, dtype=np.int64)
    for i in range(n):
        a[i], flown[i], traj[i, 0] = initial[i], lengths[i], initial[i]
    for t in range(steps):
        _step(stress, t, net, s, a, hidden, dk, geo, factor, flown, c, m, terms, held)
        for i in range(n):
            traj[i, t + 1] = a[i]
    return traj


@njit(cache=True, error_model="numpy", nogil=True)
def march_read(stress, lengths, initial, factor, lanes, net, c, m, terms, held, rows, flights):
    """march_forward's crack at the points (rows[p], flights[p]) (points,), flights sorted
    ascending, in [0, flights of stress]: the same steps, the trajectory never built (it
    is most of the march's memory traffic where a caller reads a few flights of each lane)."""
    n, steps = stress.shape
    out = np.empty(rows.shape[0])
    hidden, dk, geo = buffers(net[5], lanes)
    a, s = np.zeros(lanes), np.zeros(lanes)
    flown = np.zeros(lanes, dtype=np.int64)
    for i in range(n):
        a[i], flown[i] = initial[i], lengths[i]
    p = 0
    while p < rows.shape[0] and flights[p] == 0:
        out[p] = a[rows[p]]
        p += 1
    for t in range(steps):
        if p == rows.shape[0]:
            break
        _step(stress, t, net, s, a, hidden, dk, geo, factor, flown, c, m, terms, held)
        while p < rows.shape[0] and flights[p] == t + 1:
            out[p] = a[rows[p]]
            p += 1
    return out


@njit(cache=True, error_model="numpy")
def _step(stress, t, net, s, a, hidden, dk, geo, factor, flown, c, m, terms, held):
    """Flight t of every lane: a (lanes,) after it (a lane past its flights keeps its crack)."""
    for i in range(stress.shape[0]):
        s[i] = stress[i, t]
    stress_intensity(net, s, a, hidden, dk, geo)
    if terms.shape[0] == 0:
        for i in range(a.shape[0]):
            grown = a[i] + factor[i] * paris_growth(dk[i], c, m)
            grown = grown if grown < held else held  # nan (weights that blow up) too
            a[i] = grown if t < flown[i] else a[i]
    else:
        for i in range(a.shape[0]):
            grown = a[i] + factor[i] * nasgro_growth(dk[i], c, m, terms)
            grown = grown if grown < held else held  # +inf (past fracture) and nan too
            a[i] = grown if t < flown[i] else a[i]


@njit(cache=True, error_model="numpy", nogil=True)
def march_record(stress, lengths, initial, factor, lanes, net, c, m, terms, held, last):
    """march_forward's trajectory to flight `last`, flights-major (last + 1, lanes): what the
    adjoint of a few points (march_backward_points) reads.  Each flight's cracks are stored and
    read back contiguously, where the (aircraft, flights + 1) layout strides them: the same
    steps, ~20 % faster forward and ~17 % backward (480 lanes x 5,840 flights)."""
    n = stress.shape[0]
    traj = np.empty((last + 1, lanes))
    hidden, dk, geo = buffers(net[5], lanes)
    a, s = np.zeros(lanes), np.zeros(lanes)
    flown = np.zeros(lanes, dtype=np.int64)
    for i in range(n):
        a[i], flown[i] = initial[i], lengths[i]
    for i in range(lanes):
        traj[0, i] = a[i]
    for t in range(last):
        _step(stress, t, net, s, a, hidden, dk, geo, factor, flown, c, m, terms, held)
        for i in range(lanes):
            traj[t + 1, i] = a[i]
    return traj

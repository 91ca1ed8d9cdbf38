"""The adjoint sweep of the fast march (model/fast_march.py): d loss / d (initial crack,
network weights, growth factor) backward through model/fast_march_loops.py's Euler recurrence,
flight by flight over the same (lanes,) buffers, the network's layers for all aircraft of a
flight at once.  A step that ends held carries no gradient back."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from model.fast_march_loops import buffers, stress_intensity
from model.fast_march_math import log, paris_growth_of_log, power_of_log
from model.fast_march_packing import (
    ACTIVATION_ELU,
    ACTIVATION_TANH,
    KIND_MLP,
    KIND_PHYSICS,
    KIND_RESIDUAL,
)
from model.nasgro import growth as nasgro_growth
from model.nasgro import growth_slope as nasgro_slope


@njit(cache=True, error_model="numpy", fastmath={"reassoc"})
def _mlp_backward(theta, sizes, activations, w_off, b_off, hidden, grad, grad_theta):
    """Back-propagate grad[L, 0] (d loss / d output, per aircraft) through the L layers.

    grad (layers + 1, units, aircraft) receives d loss / d hidden of every layer, so that
    grad[0, :2] ends as d loss / d (scaled inputs); parameter gradients, summed over aircraft,
    are added into grad_theta (parameters,).  fastmath "reassoc" lets those sums use SIMD
    partial sums (keeping per-aircraft sums instead needs a (parameters, aircraft) array that
    falls out of cache for the larger networks).
    """
    n = hidden.shape[2]
    for layer in range(activations.shape[0] - 1, -1, -1):
        n_in, n_out = sizes[layer], sizes[layer + 1]
        act = activations[layer]
        for j in range(n_out):
            if act == ACTIVATION_TANH:
                for i in range(n):
                    y = hidden[layer + 1, j, i]
                    grad[layer + 1, j, i] *= 1.0 - y * y
            elif act == ACTIVATION_ELU:
                for i in range(n):
                    y = hidden[layer + 1, j, i]
                    grad[layer + 1, j, i] *= y + 1.0 if y <= 0.0 else 1.0
            total = 0.0
            for i in range(n):
                total += grad[layer + 1, j, i]
            grad_theta[b_off[layer] + j] += total
            for k in range(n_in):
                total = 0.0
                for i in range(n):
                    total += grad[layer + 1, j, i] * hidden[layer, k, i]
                grad_theta[w_off[layer] + j * n_in + k] += total
        for k in range(n_in):
            for i in range(n):
                grad[layer, k, i] = 0.0
            for j in range(n_out):
                w = theta[w_off[layer] + j * n_in + k]
                for i in range(n):
                    grad[layer, k, i] += w * grad[layer + 1, j, i]


@njit(cache=True, error_model="numpy", nogil=True)
def march_backward(stress, lengths, traj, grad_traj, factor, lanes, net, c, m, terms, held):
    """Adjoint sweep: d loss / d (initial crack (aircraft,), theta, growth factor (aircraft,)).
    A step that ends held carries no gradient back (its crack is `held` whatever came before)."""
    n, steps = stress.shape
    hidden, dk, geo = buffers(net[5], lanes)
    grad = np.zeros_like(hidden)
    a, s, rate, direct = np.zeros(lanes), np.zeros(lanes), np.zeros(lanes), np.zeros(lanes)
    adjoint, grad_factor = np.zeros(lanes), np.zeros(lanes)
    flown = np.zeros(lanes, dtype=np.int64)
    for i in range(n):
        adjoint[i], flown[i] = grad_traj[i, steps], lengths[i]
    grad_theta = np.zeros(net[4].shape[0])
    for t in range(steps - 1, -1, -1):
        for i in range(n):
            a[i], s[i] = traj[i, t], stress[i, t]
            if t < flown[i] and traj[i, t + 1] >= held:
                adjoint[i] = 0.0
        _adjoint_step(
            net, t, s, a, hidden, grad, dk, geo, rate, direct, adjoint, grad_factor, grad_theta,
            factor, flown, c, m, terms,
        )  # fmt: skip
        for i in range(n):
            adjoint[i] += grad_traj[i, t]
    return adjoint[:n].copy(), grad_theta, grad_factor[:n].copy()


@njit(cache=True, error_model="numpy", nogil=True)
def march_backward_points(
    stress, lengths, traj, rows, flights, grads, factor, lanes, net, c, m, terms, held
):
    """march_backward where the loss reads the trajectory at a few points only: grads[p] is d
    loss / d crack at (rows[p], flights[p]), the points sorted by flight (a point read twice
    adds its gradients in their order), traj march_record's.  The same arithmetic in the same
    order as march_backward given the trajectory's gradient with those sums at those points and
    zeros elsewhere, without building that (aircraft, flights + 1) array."""
    n = stress.shape[0]
    steps = traj.shape[0] - 1
    hidden, dk, geo = buffers(net[5], lanes)
    grad = np.zeros_like(hidden)
    a, s, rate, direct = np.zeros(lanes), np.zeros(lanes), np.zeros(lanes), np.zeros(lanes)
    adjoint, grad_factor, given = np.zeros(lanes), np.zeros(lanes), np.zeros(lanes)
    flown = np.zeros(lanes, dtype=np.int64)
    for i in range(n):
        flown[i] = lengths[i]
    p = rows.shape[0] - 1
    while p >= 0 and flights[p] == steps:
        adjoint[rows[p]] += grads[p]
        p -= 1
    grad_theta = np.zeros(net[4].shape[0])
    for t in range(steps - 1, -1, -1):
        for i in range(n):
            s[i] = stress[i, t]
        for i in range(lanes):
            a[i] = traj[t, i]
        for i in range(n):
            if t < flown[i] and traj[t + 1, i] >= held:
                adjoint[i] = 0.0
        _adjoint_step(
            net, t, s, a, hidden, grad, dk, geo, rate, direct, adjoint, grad_factor, grad_theta,
            factor, flown, c, m, terms,
        )  # fmt: skip
        first = p
        while p >= 0 and flights[p] == t:
            given[rows[p]] += grads[p]
            p -= 1
        for i in range(n):
            adjoint[i] += given[i]  # + 0.0 off the points, as march_backward adds
        for q in range(p + 1, first + 1):
            given[rows[q]] = 0.0
    return adjoint[:n].copy(), grad_theta, grad_factor[:n].copy()


@njit(cache=True, error_model="numpy")
def _adjoint_step(
    net, t, s, a, hidden, grad, dk, geo, rate, direct, adjoint, grad_factor, grad_theta,
    factor, flown, c, m, terms,
):  # fmt: skip
    """One flight t of the adjoint sweep, from s, a (lanes,) before it: adjoint (lanes,) from
    lambda_t to lambda_{t-1} less the loss's own d loss / d a_{t-1}, and this step's terms added
    into grad_theta and grad_factor."""
    kind, scale, lo, span, theta, sizes, activations, w_off, b_off, knots, _ = net
    tabled = knots.shape[0] > 0
    lanes = a.shape[0]
    layers = activations.shape[0]
    stress_intensity(net, s, a, hidden, dk, geo)
    if terms.shape[0] > 0:
        _nasgro_adjoint(dk, adjoint, factor, flown, t, c, m, terms, rate, grad_factor)
    else:
        for i in range(lanes):
            # lambda_t * d(da_t) / d(dK_t), and lambda_t * d(da_t) / d f = lambda_t * C dK**m,
            # both powers from one log of dK: the same bits as two `power` calls, and this sweep
            # 2.8x faster (600 lanes x 5,840 flights: 113 against 320 ms); the one power with
            # the slope as m C dK**m / dK was as fast but not bit-equal, and a fit moved by it
            # moved the drift's estimate (model.path_variability) from 2e-12 to 0.26
            log_dk = log(max(dk[i], 1e-300))
            flying = dk[i] > 0.0 and t < flown[i]
            slope = factor[i] * c * m * power_of_log(log_dk, m - 1.0)
            rate[i] = adjoint[i] * slope if flying else 0.0
            growth = paris_growth_of_log(dk[i], log_dk, c, m)
            grad_factor[i] += adjoint[i] * growth if t < flown[i] else 0.0
    if kind == KIND_MLP:
        for i in range(lanes):
            grad[layers, 0, i] = rate[i] * scale
    elif tabled:
        # d dK / d a through sqrt(pi a) and F(a): dK / (2 a) + dK F'(a) / F(a)
        for i in range(lanes):
            explicit = 0.5 * dk[i] / a[i] if a[i] > 0.0 else 0.0
            direct[i] = rate[i] * (explicit + dk[i] * geo[1, i] / geo[0, i])
    else:
        # d dK / d a through the explicit sqrt(pi a) factor: dK / (2 a)
        for i in range(lanes):
            direct[i] = rate[i] * (0.5 * dk[i] / a[i] if a[i] > 0.0 else 0.0)
    if kind == KIND_RESIDUAL and tabled:
        for i in range(lanes):
            root = math.sqrt(math.pi * max(a[i], 0.0))
            grad[layers, 0, i] = rate[i] * geo[0, i] * s[i] * root
    elif kind == KIND_RESIDUAL:
        for i in range(lanes):
            grad[layers, 0, i] = rate[i] * scale * s[i] * math.sqrt(math.pi * max(a[i], 0.0))
    if kind != KIND_PHYSICS:
        _mlp_backward(theta, sizes, activations, w_off, b_off, hidden, grad, grad_theta)
    if kind == KIND_MLP:
        for i in range(lanes):
            adjoint[i] += grad[0, 1, i] / span[1]
    elif kind == KIND_RESIDUAL:
        for i in range(lanes):
            inside = 0.0 <= (a[i] - lo[1]) / span[1] <= 1.0  # as torch.clamp's gradient
            adjoint[i] += direct[i] + (grad[0, 1, i] / span[1] if inside else 0.0)
    else:
        for i in range(lanes):
            adjoint[i] += direct[i]


@njit(cache=True, error_model="numpy")
def _nasgro_adjoint(dk, adjoint, factor, flown, t, c, m, terms, rate, grad_factor):
    """march_backward's per-lane products for the NASGRO law: rate = lambda_t f d(growth)/d dK,
    grad_factor += lambda_t growth (0 where the step's growth is 0 or infinite: such a step
    either grew nothing or ended held, and a held step's adjoint is already 0)."""
    for i in range(dk.shape[0]):
        flying = t < flown[i]
        growth = nasgro_growth(dk[i], c, m, terms)
        finite = growth < math.inf
        slope = factor[i] * nasgro_slope(dk[i], growth if finite else 0.0, m, terms)
        rate[i] = adjoint[i] * slope if flying else 0.0
        grad_factor[i] += adjoint[i] * growth if flying and finite else 0.0

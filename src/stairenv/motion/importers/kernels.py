"""Compiled kernels of the importers: the Viterbi pass (for long clips) and the bounded joint fit (for
any clip that needs one); numba's first load in a process costs ~0.5 s, its first compile ~10 s (then cached)."""

from __future__ import annotations

import math

import numpy as np

from stairenv.numba_jit import jit


@jit
def viterbi2(error: np.ndarray, step: np.ndarray) -> np.ndarray:
    """The cheapest choice per frame of two candidates: ``error`` (T, 2) per frame, ``step`` (T - 1, 2, 2)
    from the previous frame's choice to this one's; ties and NaN go as ``np.argmin`` takes them (the
    same double operations, in the same order, as ``importers.common._viterbi2``)."""
    n = error.shape[0]
    back = np.zeros((n, 2), dtype=np.int64)
    cost0, cost1 = error[0, 0], error[0, 1]
    for t in range(1, n):
        a = cost0 + step[t - 1, 0, 0]
        b = cost1 + step[t - 1, 1, 0]
        k0 = 0 if a != a else (1 if b != b or b < a else 0)
        c = cost0 + step[t - 1, 0, 1]
        d = cost1 + step[t - 1, 1, 1]
        k1 = 0 if c != c else (1 if d != d or d < c else 0)
        back[t, 0], back[t, 1] = k0, k1
        cost0, cost1 = (a if k0 == 0 else b) + error[t, 0], (c if k1 == 0 else d) + error[t, 1]
    choice = np.empty(n, dtype=np.int64)
    k = 0 if cost0 != cost0 else (1 if cost1 != cost1 or cost1 < cost0 else 0)
    choice[n - 1] = k
    for t in range(n - 1, 0, -1):
        k = back[t, k]
        choice[t - 1] = k
    return choice


# --------------------------------------------------------------------------------------
# The bounded fit of ``common._fit_in_range``, compiled: scipy's ``least_squares`` as that function
# calls it (method "trf", a 2-point finite-difference Jacobian, the "exact" trust-region solver,
# x_scale 1, linear loss) step by step, on the same residual, with the same BLAS calls for its dot and
# matrix-vector products (numba calls BLAS as numpy does), so it takes the same steps and stops at the
# same points: bit for bit on every fit of the shipped clips and the tests (should the BLAS that numba
# links round a product differently from numpy's, the fits would still agree within their tolerance).
# ~7 ms a fit in scipy, tens of microseconds here.
# --------------------------------------------------------------------------------------
_EPS = np.finfo(np.float64).eps
_DIFF_STEP = _EPS ** 0.5  # scipy's relative step of a 2-point difference


@jit
def _residual(e: np.ndarray, target: np.ndarray, bone: np.ndarray, weight: float, m: int,
              out: np.ndarray) -> None:
    """``common._fit_in_range``'s residual at ``e`` into ``out`` (m,): the matrix difference
    Rx Ry Rz - target (9), then, if m is 12, ``weight`` times its product with ``bone`` (3)."""
    ca, sa = math.cos(e[0]), math.sin(e[0])
    cb, sb = math.cos(e[1]), math.sin(e[1])
    cc, sc = math.cos(e[2]), math.sin(e[2])
    out[0] = cb * cc - target[0, 0]
    out[1] = -cb * sc - target[0, 1]
    out[2] = sb - target[0, 2]
    out[3] = ca * sc + sa * sb * cc - target[1, 0]
    out[4] = ca * cc - sa * sb * sc - target[1, 1]
    out[5] = -sa * cb - target[1, 2]
    out[6] = sa * sc - ca * sb * cc - target[2, 0]
    out[7] = sa * cc + ca * sb * sc - target[2, 1]
    out[8] = ca * cb - target[2, 2]
    if m == 12:  # weight * (diff @ bone), the same BLAS product as numpy's
        moved = out[:9].copy().reshape(3, 3) @ bone
        for i in range(3):
            out[9 + i] = weight * moved[i]


@jit
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """``np.dot`` of two vectors: the BLAS call numpy makes, so the same rounding."""
    return np.dot(a, b)


@jit
def _norm(a: np.ndarray) -> float:
    return math.sqrt(_dot(a, a))


@jit
def _pairwise_sum_squares(a: np.ndarray) -> float:
    """``np.sum(a ** 2)`` for up to 128 values, as numpy adds them (eight running sums, then the rest)."""
    n = a.shape[0]
    if n < 8:
        total = 0.0
        for i in range(n):
            total += a[i] * a[i]
        return total
    r = np.empty(8)
    for j in range(8):
        r[j] = a[j] * a[j]
    i = 8
    while i < n - n % 8:
        for j in range(8):
            r[j] += a[i + j] * a[i + j]
        i += 8
    total = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        total += a[i] * a[i]
        i += 1
    return total


@jit
def _strictly_feasible(x: np.ndarray, lb: np.ndarray, ub: np.ndarray, rstep: float) -> np.ndarray:
    """scipy's ``make_strictly_feasible``."""
    out = x.copy()
    for i in range(x.shape[0]):
        if rstep == 0.0:
            active = -1 if x[i] <= lb[i] else 0
            if x[i] >= ub[i]:
                active = 1
            if active == -1:
                out[i] = np.nextafter(lb[i], ub[i])
            elif active == 1:
                out[i] = np.nextafter(ub[i], lb[i])
        else:
            lower, upper = x[i] - lb[i], ub[i] - x[i]
            active = 0
            if lower <= min(upper, rstep * max(1.0, abs(lb[i]))):
                active = -1
            if upper <= min(lower, rstep * max(1.0, abs(ub[i]))):
                active = 1
            if active == -1:
                out[i] = lb[i] + rstep * max(1.0, abs(lb[i]))
            elif active == 1:
                out[i] = ub[i] - rstep * max(1.0, abs(ub[i]))
        if out[i] < lb[i] or out[i] > ub[i]:
            out[i] = 0.5 * (lb[i] + ub[i])
    return out


@jit
def _jacobian(x: np.ndarray, f0: np.ndarray, lb: np.ndarray, ub: np.ndarray, target: np.ndarray,
              bone: np.ndarray, weight: float, m: int) -> np.ndarray:
    """scipy's ``approx_derivative(method="2-point", bounds=(lb, ub))``: (m, 3)."""
    n = x.shape[0]
    jac_t = np.empty((n, m))  # scipy builds the transpose (C order), its Jacobian is the F-order view
    f1 = np.empty(m)
    for i in range(n):
        h = _DIFF_STEP * (1.0 if x[i] >= 0 else -1.0) * max(1.0, abs(x[i]))
        lower, upper = x[i] - lb[i], ub[i] - x[i]
        moved = x[i] + h
        fitting = abs(h) <= max(lower, upper)
        if (moved < lb[i] or moved > ub[i]) and fitting:
            h = -h
        if not fitting:
            h = upper if upper >= lower else -lower
        x1 = x.copy()
        x1[i] = x[i] + h
        _residual(x1, target, bone, weight, m, f1)
        dx = (x[i] + h) - x[i]
        for k in range(m):
            jac_t[i, k] = (f1[k] - f0[k]) / dx
    return jac_t.T


@jit
def _cl_scaling(x: np.ndarray, g: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """scipy's ``CL_scaling_vector`` (finite bounds)."""
    v = np.ones_like(x)
    dv = np.zeros_like(x)
    for i in range(x.shape[0]):
        if g[i] < 0:
            v[i], dv[i] = ub[i] - x[i], -1.0
        if g[i] > 0:
            v[i], dv[i] = x[i] - lb[i], 1.0
    return v, dv


@jit
def _step_to_bound(x: np.ndarray, s: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> tuple[float, np.ndarray]:
    """scipy's ``step_size_to_bound``."""
    n = x.shape[0]
    steps = np.full(n, np.inf)
    for i in range(n):
        if s[i] != 0:
            steps[i] = max((lb[i] - x[i]) / s[i], (ub[i] - x[i]) / s[i])
    least = steps.min()
    hits = np.zeros(n, dtype=np.int64)
    for i in range(n):
        if steps[i] == least:
            hits[i] = 1 if s[i] > 0 else (-1 if s[i] < 0 else 0)
    return least, hits


@jit
def _quadratic(jh: np.ndarray, gh: np.ndarray, s: np.ndarray, diag: np.ndarray) -> float:
    """scipy's ``evaluate_quadratic`` (one step)."""
    js = jh @ s
    return 0.5 * (_dot(js, js) + _dot(s * diag, s)) + _dot(s, gh)


@jit
def _minimize_1d(a: float, b: float, lo: float, hi: float, c: float) -> tuple[float, float]:
    """scipy's ``minimize_quadratic_1d``: of lo, hi and the extremum between them, the first with the
    least value (``np.argmin``: a NaN value counts as the least)."""
    ts = np.empty(3)
    ts[0], ts[1] = lo, hi
    count = 2
    if a != 0:
        ext = -0.5 * b / a
        if lo < ext < hi:
            ts[2] = ext
            count = 3
    best_t, best_y = ts[0], ts[0] * (a * ts[0] + b) + c
    for j in range(1, count):
        y = ts[j] * (a * ts[j] + b) + c
        if best_y != best_y:
            break
        if y != y or y < best_y:
            best_t, best_y = ts[j], y
    return best_t, best_y


@jit
def _select_step(x, jh, diag_h, g_h, p, p_h, d, delta, lb, ub, theta):
    """scipy's ``trf.select_step``: the trust-region step, its reflection off the bound it hits,
    or the scaled gradient step, whichever the quadratic model likes best."""
    n = x.shape[0]
    inside = True
    for i in range(n):
        if not (lb[i] <= x[i] + p[i] <= ub[i]):
            inside = False
    if inside:
        return p, p_h, -_quadratic(jh, g_h, p_h, diag_h)
    p_stride, hits = _step_to_bound(x, p, lb, ub)
    r_h = p_h.copy()
    for i in range(n):
        if hits[i] != 0:
            r_h[i] *= -1
    r = d * r_h
    p = p * p_stride
    p_h = p_h * p_stride
    x_on_bound = x + p
    # intersect_trust_region(p_h, r_h, delta): the positive root
    qa = _dot(r_h, r_h)
    if qa == 0:
        raise ValueError("`s` is zero.")
    qb = _dot(p_h, r_h)
    qc = _dot(p_h, p_h) - delta ** 2
    if qc > 0:
        raise ValueError("`x` is not within the trust region.")
    root = math.sqrt(qb * qb - qa * qc)
    q = -(qb + math.copysign(root, qb))
    t1, t2 = q / qa, qc / q
    to_tr = t2 if t1 < t2 else t1
    to_bound, _ = _step_to_bound(x_on_bound, r, lb, ub)
    r_stride = min(to_bound, to_tr)
    if r_stride > 0:
        r_lo = (1 - theta) * p_stride / r_stride
        r_hi = theta * to_bound if r_stride == to_bound else to_tr
    else:
        r_lo, r_hi = 0.0, -1.0
    if r_lo <= r_hi:
        v = jh @ r_h
        u = jh @ p_h
        a = 0.5 * (_dot(v, v) + _dot(r_h * diag_h, r_h))
        b = _dot(g_h, r_h) + _dot(u, v) + _dot(p_h * diag_h, r_h)
        c = 0.5 * _dot(u, u) + _dot(g_h, p_h) + 0.5 * _dot(p_h * diag_h, p_h)
        r_stride, r_value = _minimize_1d(a, b, r_lo, r_hi, c)
        r_h = r_h * r_stride + p_h
        r = r_h * d
    else:
        r_value = np.inf
    p = p * theta
    p_h = p_h * theta
    p_value = _quadratic(jh, g_h, p_h, diag_h)
    ag_h = -g_h
    ag = d * ag_h
    to_tr = delta / _norm(ag_h)
    to_bound, _ = _step_to_bound(x, ag, lb, ub)
    ag_stride = theta * to_bound if to_bound < to_tr else to_tr
    v = jh @ ag_h
    a = 0.5 * (_dot(v, v) + _dot(ag_h * diag_h, ag_h))
    b = _dot(g_h, ag_h)
    ag_stride, ag_value = _minimize_1d(a, b, 0.0, ag_stride, 0.0)
    ag_h = ag_h * ag_stride
    ag = ag * ag_stride
    if p_value < r_value and p_value < ag_value:
        return p, p_h, -p_value
    if r_value < p_value and r_value < ag_value:
        return r, r_h, -r_value
    return ag, ag_h, -ag_value


@jit
def _phi(alpha: float, suf: np.ndarray, s: np.ndarray, delta: float) -> tuple[float, float]:
    denom = s ** 2 + alpha
    p_norm = _norm(suf / denom)
    total = 0.0
    for i in range(s.shape[0]):
        total += suf[i] ** 2 / math.pow(denom[i], 3.0)
    return p_norm - delta, -total / p_norm


@jit
def _trust_region_step(n: int, m: int, uf: np.ndarray, s: np.ndarray, v: np.ndarray, delta: float,
                       alpha: float) -> tuple[np.ndarray, float]:
    """scipy's ``solve_lsq_trust_region`` (rtol 0.01, 10 iterations): the step and the new alpha."""
    suf = s * uf
    full_rank = m >= n and s[-1] > _EPS * m * s[0]
    if full_rank:
        p = -(v @ (uf / s))
        if _norm(p) <= delta:
            return p, 0.0
    alpha_upper = _norm(suf) / delta
    alpha_lower = 0.0
    if full_rank:
        phi, phi_prime = _phi(0.0, suf, s, delta)
        alpha_lower = -phi / phi_prime
    if not full_rank and alpha == 0:
        alpha = max(0.001 * alpha_upper, math.pow(alpha_lower * alpha_upper, 0.5))
    for _ in range(10):
        if alpha < alpha_lower or alpha > alpha_upper:
            alpha = max(0.001 * alpha_upper, math.pow(alpha_lower * alpha_upper, 0.5))
        phi, phi_prime = _phi(alpha, suf, s, delta)
        if phi < 0:
            alpha_upper = alpha
        ratio = phi / phi_prime
        alpha_lower = max(alpha_lower, alpha - ratio)
        alpha -= (phi + delta) * ratio / delta
        if abs(phi) < 0.01 * delta:
            break
    p = -(v @ (suf / (s ** 2 + alpha)))
    p *= delta / _norm(p)
    return p, alpha


@jit
def _least_squares(x0, lb, ub, target, bone, weight, m, ftol, xtol, gtol):
    """scipy's ``least_squares(residual, x0, bounds=(lb, ub), xtol=xtol, ftol=ftol)`` with the defaults
    the importer leaves (``trf.trf_bounds``): the solution and its residual (m,)."""
    n = x0.shape[0]
    x = _strictly_feasible(x0, lb, ub, 1e-10)
    f = np.empty(m)
    _residual(x, target, bone, weight, m, f)
    jac = _jacobian(x, f, lb, ub, target, bone, weight, m)
    nfev, max_nfev = 1, 100 * n
    cost = 0.5 * _dot(f, f)
    g = jac.T @ f
    v, dv = _cl_scaling(x, g, lb, ub)
    delta = _norm(x / np.sqrt(v))
    if delta == 0:
        delta = 1.0
    alpha = 0.0
    status = 0
    augmented = np.zeros((m + n, n))
    f_augmented = np.zeros(m + n)
    f_new = np.empty(m)
    while True:
        v, dv = _cl_scaling(x, g, lb, ub)
        g_norm = np.abs(g * v).max()
        if g_norm < gtol:
            status = 1
        if status != 0 or nfev == max_nfev:
            break
        d = np.sqrt(v)
        diag_h = g * dv
        g_h = d * g
        f_augmented[:m] = f
        for k in range(m):
            for i in range(n):
                augmented[k, i] = jac[k, i] * d[i]
        for i in range(n):
            augmented[m + i, i] = math.sqrt(diag_h[i])
        jh = augmented[:m].copy()
        u, s, vt = np.linalg.svd(augmented, full_matrices=False)
        vv = vt.T
        uf = u.T @ f_augmented
        theta = max(0.995, 1 - g_norm)
        actual_reduction = -1.0
        cost_new = cost
        x_new = x
        while actual_reduction <= 0 and nfev < max_nfev:
            p_h, alpha = _trust_region_step(n, m, uf, s, vv, delta, alpha)
            p = d * p_h
            step, step_h, predicted_reduction = _select_step(x, jh, diag_h, g_h, p, p_h, d, delta, lb, ub, theta)
            x_new = _strictly_feasible(x + step, lb, ub, 0.0)
            _residual(x_new, target, bone, weight, m, f_new)
            nfev += 1
            step_h_norm = _norm(step_h)
            if not np.all(np.isfinite(f_new)):
                delta = 0.25 * step_h_norm
                continue
            cost_new = 0.5 * _dot(f_new, f_new)
            actual_reduction = cost - cost_new
            # update_tr_radius
            if predicted_reduction > 0:
                ratio = actual_reduction / predicted_reduction
            elif predicted_reduction == actual_reduction == 0:
                ratio = 1.0
            else:
                ratio = 0.0
            delta_new = delta
            if ratio < 0.25:
                delta_new = 0.25 * step_h_norm
            elif ratio > 0.75 and step_h_norm > 0.95 * delta:
                delta_new = 2.0 * delta
            # check_termination
            ftol_ok = actual_reduction < ftol * cost and ratio > 0.25
            xtol_ok = _norm(step) < xtol * (xtol + _norm(x))
            if ftol_ok and xtol_ok:
                status = 4
            elif ftol_ok:
                status = 2
            elif xtol_ok:
                status = 3
            if status != 0:
                break
            alpha *= delta / delta_new
            delta = delta_new
        if actual_reduction > 0:
            x = x_new
            f = f_new.copy()
            cost = cost_new
            jac = _jacobian(x, f, lb, ub, target, bone, weight, m)
            g = jac.T @ f
    return x, f


@jit
def fit_in_range(targets: np.ndarray, starts: np.ndarray, low: np.ndarray, high: np.ndarray, bone: np.ndarray,
                 weight: float, m: int) -> np.ndarray:
    """``common._fit_in_range`` of each (3, 3) rotation matrix ``targets[k]`` from ``starts[k]`` (3,):
    the bounded fit within [low + 1e-9, high - 1e-9] (xtol = ftol = 1e-10), clamped to [low, high],
    where it lowers the residual's sum of squares below the start's, else the start. ``m``: 12 with a
    bone (``weight`` its weight), 9 without."""
    out = starts.copy()
    lo, hi = low + 1e-9, high - 1e-9
    r_start = np.empty(m)
    for k in range(targets.shape[0]):
        start = starts[k]
        x0 = np.minimum(np.maximum(start, lo), hi)
        x, f = _least_squares(x0, lo, hi, targets[k], bone, weight, m, 1e-10, 1e-10, 1e-8)
        _residual(start, targets[k], bone, weight, m, r_start)
        if _pairwise_sum_squares(f) < _pairwise_sum_squares(r_start):
            out[k] = np.minimum(np.maximum(x, low), high)
    return out


# --------------------------------------------------------------------------------------
# BVH frame values
# --------------------------------------------------------------------------------------
_POW10 = np.array([10.0 ** k for k in range(23)])  # exact doubles: 10^0 .. 10^22
_MAX_EXACT = 2 ** 53


@jit
def parse_frames(text: np.ndarray, rows: int, columns: int) -> tuple[np.ndarray, int]:
    """The numbers of ``rows`` lines of ASCII ``text`` (uint8; lines joined by newlines; lines of spaces
    and tabs only are skipped), ``columns`` a line, as (rows, columns) doubles, and 0; or a status saying
    why it did not: 1 where a line holds another number of values (or other than ``rows`` lines hold
    values), 2 where a byte or a number falls outside the plain
    decimal form ``[+-](digits[.digits] | .digits)[(e|E)[+-]digits]`` separated by spaces or tabs, or
    where a number has more than 2^53 as its digits or a power of ten beyond 1e22. Within those, each
    value is the exact product or quotient of two exact doubles (its digits and a power of ten), so
    rounded once: what ``float()`` of the same text gives, bit for bit (Clinger's fast path)."""
    out = np.empty((rows, columns))
    n = text.shape[0]
    i, row, col = 0, 0, 0
    while i < n:
        c = text[i]
        if c == 32 or c == 9:  # space, tab
            i += 1
            continue
        if c == 10:  # newline: a line of values must be complete; blank lines are skipped
            if col != 0:
                if col != columns:
                    return out, 1
                row += 1
                col = 0
            i += 1
            continue
        if row >= rows or col >= columns:
            return out, 1
        negative = False
        if c == 43 or c == 45:  # + -
            negative = c == 45
            i += 1
        mantissa, digits, scale, exponent = 0, 0, 0, 0
        dot = False
        while i < n:  # digits, with at most one "." among or around them
            d = text[i]
            if 48 <= d <= 57:
                if mantissa > _MAX_EXACT:
                    return out, 2
                mantissa = mantissa * 10 + (d - 48)
                digits += 1
                if dot:
                    scale += 1
            elif d == 46 and not dot:
                dot = True
            else:
                break
            i += 1
        if digits == 0:
            return out, 2
        if i < n and (text[i] == 101 or text[i] == 69):  # e E
            i += 1
            exp_negative = False
            if i < n and (text[i] == 43 or text[i] == 45):
                exp_negative = text[i] == 45
                i += 1
            exp_digits = 0
            while i < n and 48 <= text[i] <= 57:
                if exponent < 100_000:
                    exponent = exponent * 10 + (text[i] - 48)
                exp_digits += 1
                i += 1
            if exp_digits == 0:
                return out, 2
            if exp_negative:
                exponent = -exponent
        if i < n and not (text[i] == 32 or text[i] == 9 or text[i] == 10):
            return out, 2
        if mantissa > _MAX_EXACT:
            return out, 2
        power = exponent - scale
        if power > 22 or power < -22:
            return out, 2
        value = float(mantissa)
        if power >= 0:
            value = value * _POW10[power]
        else:
            value = value / _POW10[-power]
        out[row, col] = -value if negative else value
        col += 1
    if col != 0:  # the last line had no newline after it
        if col != columns:
            return out, 1
        row += 1
    if row != rows:
        return out, 1
    return out, 0

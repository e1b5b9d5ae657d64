"""Extended soil models as one family each, with analytic Jacobians.

Sinkage (Eqs. 7–8 extended)::

    p = k_b · S · z^(n + D)                      k_b = kc/b + kφ (Bekker) or k (Bernstein)
    S = exp(Σ s_i·F_i),  D = Σ d_i·G_i           per-sample features of the test's setup

and, for plates flagged as narrow, the two-stage softening of the paper's Fig. 9 beyond a
critical sinkage z_c: p = p(z_c) + f·(p − p(z_c)) for z > z_c.  Velocity dependence
k·(v/v_ref)^a is S with F = ln(v/v_ref); a covariate effect on k or n is S or D with the
covariate's features.

Shear (Eq. 13 extended)::

    τ = (c·S_c + σ·tan φ·S_t)·(1 − exp(−j/(K·S_K)))

with S_c = exp(Σ θ_c·F), S_t = exp(Σ θ_t·F), S_K = exp(Σ θ_K·F) for a covariate, or the
side-wall terms of the torque conversion (Eq. 12 ignores them): S_c = 1 + a,
S_t = 1 + a·K0, a = 3h(r_i² + r_o²)/(r_o³ − r_i³) for grousers of height h (docs/simulator.md).

Every family is written as ``(f(θ), J(θ))`` closures over fixed inputs, for
:func:`soilstats.identify`.  The base parameters keep the units and plausible bounds of
:data:`BEKKER`, :data:`BERNSTEIN` and :data:`JANOSI`; the side-wall ratio is
:func:`~soilstats.models.shear.side_wall_ratio`.  Discovery (``soilstats.discovery``) chooses
which family to fit; the equations live here with the base models.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .shear import RAD_PER_DEG

__all__ = ["ShearLayout", "SinkageLayout", "shear_family", "sinkage_family"]


@dataclass(frozen=True)
class SinkageLayout:
    """Parameter layout: base (kc, kφ, n or k, n), then s (stiffness), d (exponent), softening."""

    bekker: bool
    n_s: int = 0
    n_d: int = 0
    soften: bool = False

    @property
    def n_base(self) -> int:
        return 3 if self.bekker else 2

    @property
    def size(self) -> int:
        return self.n_base + self.n_s + self.n_d + 2 * self.soften


def sinkage_family(layout: SinkageLayout, b, z, fs=None, gd=None, soft=None):
    """(f(θ), J(θ)) of the extended pressure–sinkage family; z > 0 [m], b [m], p [Pa].

    ``fs`` (N, n_s) and ``gd`` (N, n_d) are the stiffness and exponent features; ``soft`` (N,)
    marks the samples of narrow plates that soften beyond z_c.
    """
    b = np.asarray(b, float)
    lnz = np.log(np.asarray(z, float))
    inv_b = 1.0 / b
    nb = layout.n_base

    def parts(theta):
        theta = np.asarray(theta, float)
        kb = theta[0] * inv_b + theta[1] if layout.bekker else np.full(lnz.size, theta[0])
        n = theta[nb - 1]
        s = theta[nb : nb + layout.n_s]
        d = theta[nb + layout.n_s : nb + layout.n_s + layout.n_d]
        scale = np.exp(fs @ s) if layout.n_s else np.ones(lnz.size)
        expo = n + (gd @ d if layout.n_d else 0.0)
        zn = np.exp(expo * lnz)
        return kb, scale, expo, zn

    def soft_terms(theta, k_eff, expo):
        zc, frac = theta[-2], theta[-1]
        lzc = np.log(zc) if zc > 0 else -np.inf
        pc = k_eff * np.exp(expo * lzc)
        beyond = soft & (lnz > lzc)
        return zc, frac, lzc, pc, beyond

    def f(theta):
        kb, scale, expo, zn = parts(theta)
        p = kb * scale * zn
        if layout.soften:
            _, frac, _, pc, beyond = soft_terms(theta, kb * scale, expo)
            p = np.where(beyond, pc + frac * (p - pc), p)
        return p

    def jac(theta):
        kb, scale, expo, zn = parts(theta)
        k_eff = kb * scale
        p = k_eff * zn
        cols = [zn * scale * inv_b, zn * scale] if layout.bekker else [zn * scale]
        cols.append(p * lnz)
        cols += [p * fs[:, i] for i in range(layout.n_s)]
        cols += [p * lnz * gd[:, i] for i in range(layout.n_d)]
        if not layout.soften:
            return np.column_stack(cols)
        zc, frac, lzc, pc, beyond = soft_terms(theta, k_eff, expo)
        zcn = pc / np.where(k_eff != 0, k_eff, 1.0)
        ccols = [zcn * scale * inv_b, zcn * scale] if layout.bekker else [zcn * scale]
        ccols.append(pc * lzc)
        ccols += [pc * fs[:, i] for i in range(layout.n_s)]
        ccols += [pc * lzc * gd[:, i] for i in range(layout.n_d)]
        out = [
            np.where(beyond, (1 - frac) * cc + frac * c, c)
            for c, cc in zip(cols, ccols, strict=True)
        ]
        out.append(np.where(beyond, (1 - frac) * pc * expo / zc, 0.0))
        out.append(np.where(beyond, p - pc, 0.0))
        return np.column_stack(out)

    return f, jac


@dataclass(frozen=True)
class ShearLayout:
    """Parameter layout: c, φ [deg], K, then θ_c, θ_t, θ_K features, or K0 (side walls)."""

    n_c: int = 0
    n_t: int = 0
    n_k: int = 0
    side_walls: bool = False

    @property
    def size(self) -> int:
        return 3 + self.n_c + self.n_t + self.n_k + self.side_walls


def shear_family(layout: ShearLayout, sigma, j, fc=None, ft=None, fk=None, a=None):
    """(f(θ), J(θ)) of the extended Janosi–Hanamoto family; σ, τ in Pa, j and K in m.

    Covariate factors and side walls combine: τ = (c·S_c·(1 + a) + σ·tan φ·S_t·(1 + a·K0))·
    (1 − exp(−j/(K·S_K))), with the wall terms only when ``layout.side_walls``.
    """
    sigma = np.asarray(sigma, float)
    j = np.asarray(j, float)
    i_c, i_t, i_k = 3, 3 + layout.n_c, 3 + layout.n_c + layout.n_t
    i_end = i_k + layout.n_k
    ones = np.ones(j.size)

    def parts(theta):
        theta = np.asarray(theta, float)
        c, phi, k = theta[0], theta[1], theta[2]
        t = np.tan(phi * RAD_PER_DEG)
        s_c = np.exp(fc @ theta[i_c:i_t]) if layout.n_c else ones
        s_t = np.exp(ft @ theta[i_t:i_k]) if layout.n_t else ones
        if layout.side_walls:
            s_c = s_c * (1.0 + a)
            s_t = s_t * (1.0 + a * theta[-1])
        s_k = np.exp(fk @ theta[i_k:i_end]) if layout.n_k else ones
        k_eff = k * s_k
        decay = np.exp(-j / k_eff)
        return c, t, phi, s_c, s_t, k_eff, decay

    def f(theta):
        c, t, _, s_c, s_t, _, decay = parts(theta)
        return (c * s_c + sigma * t * s_t) * (1.0 - decay)

    def jac(theta):
        c, t, phi, s_c, s_t, k_eff, decay = parts(theta)
        g = 1.0 - decay
        level = c * s_c + sigma * t * s_t
        dk_eff = -level * decay * j / k_eff**2  # ∂τ/∂K_eff
        cols = [
            s_c * g,
            sigma * s_t * RAD_PER_DEG / np.cos(phi * RAD_PER_DEG) ** 2 * g,
            dk_eff * k_eff / theta[2],
        ]
        cols += [c * s_c * fc[:, i] * g for i in range(layout.n_c)]
        cols += [sigma * t * s_t * ft[:, i] * g for i in range(layout.n_t)]
        cols += [dk_eff * k_eff * fk[:, i] for i in range(layout.n_k)]
        if layout.side_walls:
            # ∂/∂K0 of σ·tan φ·S_t·(1 + a·K0): S_t without its wall factor, times a.
            cols.append(sigma * t * s_t / (1.0 + a * theta[-1]) * a * g)
        return np.column_stack(cols)

    return f, jac

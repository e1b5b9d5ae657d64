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

Any registered model (docs/conventions.md, "The model record") extends the generic way::

    y = S · f(x, θ with its exponent n + D)      S = exp(Σ s_i·F_i),  D = Σ d_i·G_i

(:class:`ModelFamily`): a stiffness-type factor on the output and an offset on the sinkage
exponent, which for Bekker and Bernstein are those of the sinkage family above.

Every family is an object over fixed inputs with ``f(θ)`` (N,) and ``jac(θ)`` (N, p) —
``f, jac = family`` unpacks them — and :meth:`~SinkageFamily.model`, a :class:`Model` whose
``prepare`` gives :func:`soilstats.identify` its fast path: the weights folded in, f and J
sharing their common factors (the optimiser asks for J at the point whose residual it has
just accepted, so the model's parts at the last θ are kept), and J written row by row into
one preallocated (p, N) array, the layout the optimiser multiplies with.  Each weighted row
is w × (the same expression as the unweighted column, in the same order of operations), so
the fast path gives bit for bit the values of ``w·f`` and ``w·J``; a factor exactly 1 (no
covariate term) is skipped, which changes no bit either.

The base parameters keep the units and plausible bounds of :data:`BEKKER`,
:data:`BERNSTEIN` and :data:`JANOSI`; the side-wall ratio is
:func:`~soilstats.models.shear.side_wall_ratio`.  Discovery (``soilstats.discovery``)
chooses which family to fit; the equations live here with the base models.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError
from .base import Model
from .shear import RAD_PER_DEG

__all__ = [
    "ModelFamily",
    "ShearFamily",
    "ShearLayout",
    "SinkageFamily",
    "SinkageLayout",
    "model_family",
    "shear_family",
    "sinkage_family",
]


def _rows_of(features: ArrayLike | None) -> Any:
    """(m, N) contiguous rows of an (N, m) feature matrix (the Jacobian's layout).

    None without features; a family reads it only where their count is not 0 (typed Any:
    the count is the guard, which a type cannot follow), as :func:`_product_of`'s."""
    return None if features is None else np.ascontiguousarray(np.asarray(features, float).T)


class _Product:
    """θ ↦ F·θ for an (N, m) feature matrix F, once per θ of every fit iteration.

    Per-level features (one indicator per level besides the reference: each sample has at
    most one 1) give F·θ = θ of the sample's level, 0 for the reference: one gather instead
    of m passes over the samples — the same numbers, as a sum of one term and zeros is that
    term.  Other features take the matrix product.
    """

    def __init__(self, features: ArrayLike) -> None:
        self.matrix = np.asarray(features, float)
        self.codes = None
        indicator = np.all((self.matrix == 0.0) | (self.matrix == 1.0))
        if indicator and np.all(self.matrix.sum(axis=1) <= 1.0):
            # Column of each sample's 1, or −1 (the reference) which picks the appended 0.
            self.codes = np.where(self.matrix.any(axis=1), self.matrix.argmax(axis=1), -1)

    def __call__(self, coef: np.ndarray) -> np.ndarray:
        if self.codes is None:
            return self.matrix @ coef
        return np.append(coef, 0.0)[self.codes]


def _product_of(features: ArrayLike | None) -> Any:
    return None if features is None else _Product(features)


class _Family:
    """What the sinkage and shear families share: the (f, J) pair, the part cache, a Model."""

    size: int

    def __init__(self) -> None:
        self._key: tuple | None = None
        self._parts: tuple = ()  # of self._key: none yet

    def _scale_and_offset_features(self, fs: ArrayLike | None, gd: ArrayLike | None) -> None:
        """The features of the scale (``fs``) and offset (``gd``) terms: their rows and their
        products with coefficients (:func:`_rows_of`, :func:`_product_of`)."""
        self.fs_rows, self.gd_rows = _rows_of(fs), _rows_of(gd)
        self.fs_times, self.gd_times = _product_of(fs), _product_of(gd)

    def _parts_at(self, theta: np.ndarray) -> tuple:
        """The θ-dependent parts, computed once per θ: f and J at the same point share them."""
        key = tuple(theta.tolist())
        if key != self._key:
            self._parts = self._compute(theta)
            self._key = key
        return self._parts

    def _compute(self, theta: np.ndarray) -> tuple:  # pragma: no cover (abstract)
        raise NotImplementedError

    def value(self, theta: np.ndarray) -> np.ndarray:  # pragma: no cover (abstract)
        raise NotImplementedError

    def rows(
        self, theta: np.ndarray, w: np.ndarray | None = None
    ) -> np.ndarray:  # pragma: no cover (abstract)
        raise NotImplementedError

    def f(self, theta: ArrayLike) -> np.ndarray:
        """The model's values at θ, (N,) (a copy: the cached parts stay untouched)."""
        return np.array(self.value(np.asarray(theta, float)))

    def jac(self, theta: ArrayLike) -> np.ndarray:
        """∂f/∂θ, (N, p) (a transposed view of the (p, N) rows)."""
        return self.rows(np.asarray(theta, float)).T

    def __iter__(self) -> Iterator[Callable[[ArrayLike], np.ndarray]]:
        """``f, jac = family``."""
        return iter((self.f, self.jac))

    def weighted(self, w: ArrayLike) -> tuple:
        """(θ ↦ w·f(θ), θ ↦ (w·∂f/∂θ)ᵀ as (p, N) rows): the closures of ``Model.prepare``."""
        w = np.asarray(w, float)

        def f_weighted(theta):
            return self.value(np.asarray(theta, float)) * w

        def jac_rows(theta):
            return self.rows(np.asarray(theta, float), w)

        return f_weighted, jac_rows

    def _output(self) -> str:
        return "p [Pa]" if isinstance(self, SinkageFamily) else "tau [Pa]"

    def model(self, names: Sequence[str], units: Sequence[str], bounds: dict, name: str) -> Model:
        """This family as a :class:`Model` over x = sample index (the inputs are fixed here)."""
        unbounded = (-np.inf, np.inf)
        return Model(
            name=name,
            equation="extended family (soilstats.models.extended)",
            inputs=("sample index",),
            output=self._output(),
            param_names=tuple(names),
            units=tuple(units),
            bounds=tuple(bounds.get(n, unbounded) for n in names),
            func=lambda _x, *theta: self.f(np.asarray(theta, float)),
            jac=lambda _x, *theta: self.jac(np.asarray(theta, float)),
            prepare=lambda _x, w: self.weighted(w),
        )


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


class SinkageFamily(_Family):
    """The extended pressure–sinkage family over fixed z > 0 [m], b [m]; p in Pa.

    ``fs`` (N, n_s) and ``gd`` (N, n_d) are the stiffness and exponent features; ``soft``
    (N,) marks the samples of narrow plates that soften beyond z_c.
    """

    def __init__(
        self,
        layout: SinkageLayout,
        b: ArrayLike,
        z: ArrayLike,
        fs: ArrayLike | None = None,
        gd: ArrayLike | None = None,
        soft: ArrayLike | None = None,
    ) -> None:
        super().__init__()
        self.layout = layout
        self.size = layout.size
        self.inv_b = 1.0 / np.asarray(b, float)
        self.lnz = np.log(np.asarray(z, float))
        self._scale_and_offset_features(fs, gd)
        self.soft = None if soft is None else np.asarray(soft, bool)

    def _compute(self, theta):
        lay, nb = self.layout, self.layout.n_base
        # k_b as a vector (Bekker) or the scalar k (Bernstein): a scalar times an array rounds
        # exactly as the array of that scalar would.
        kb = theta[0] * self.inv_b + theta[1] if lay.bekker else theta[0]
        n = theta[nb - 1]
        scale = None  # S = 1: no stiffness term (a product with 1 is exact, so it is skipped)
        if lay.n_s:
            scale = np.exp(self.fs_times(theta[nb : nb + lay.n_s]))
        expo = n
        if lay.n_d:
            expo = n + self.gd_times(theta[nb + lay.n_s : nb + lay.n_s + lay.n_d])
        zn = np.exp(expo * self.lnz)
        k_eff = kb if scale is None else kb * scale
        p = k_eff * zn
        soft = None
        if lay.soften:
            zc, frac = theta[-2], theta[-1]
            lzc = np.log(zc) if zc > 0 else -np.inf
            pc = k_eff * np.exp(expo * lzc)
            beyond = self.soft & (self.lnz > lzc)
            soft = (zc, frac, lzc, pc, beyond)
        return kb, scale, expo, zn, k_eff, p, soft

    def value(self, theta: np.ndarray) -> np.ndarray:
        _, _, _, _, _, p, soft = self._parts_at(theta)
        if soft is None:
            return p
        _, frac, _, pc, beyond = soft
        return np.where(beyond, pc + frac * (p - pc), p)

    def weighted(self, w: ArrayLike) -> tuple:
        """(θ ↦ w·p(θ), θ ↦ (w·∂p/∂θ)ᵀ as (p, N) rows), the closures of ``Model.prepare``.

        The weights enter the fixed inputs once (w/b), and w·p at the last θ is kept: it is
        the common factor of the n, stiffness and exponent rows, and the optimiser asks for
        the Jacobian at the point whose residual it has just accepted.  Each row then costs
        one product over the samples.
        """
        w = np.asarray(w, float)
        w_inv_b = w * self.inv_b
        last: dict = {"key": None, "wp": None, "wf": None}

        def weighted_parts(theta):
            key = tuple(theta.tolist())
            if key != last["key"]:
                _, _, _, _, _, p, soft = self._parts_at(theta)
                wp = p * w
                wf = wp if soft is None else self.value(theta) * w
                last.update(key=key, wp=wp, wf=wf)
            return last["wp"], last["wf"]

        def f_weighted(theta):
            return weighted_parts(np.asarray(theta, float))[1]

        def jac_rows(theta):
            theta = np.asarray(theta, float)
            return self._rows(theta, w, w_inv_b, weighted_parts(theta)[0])

        return f_weighted, jac_rows

    def rows(self, theta: ArrayLike, w: ArrayLike | None = None) -> np.ndarray:
        """(p, N) rows of ∂p/∂θ, times the weights ``w`` when given."""
        theta = np.asarray(theta, float)
        p = self._parts_at(theta)[5]
        if w is None:
            return self._rows(theta, None, self.inv_b, p)
        w = np.asarray(w, float)
        return self._rows(theta, w, w * self.inv_b, p * w)

    def _rows(
        self, theta: np.ndarray, w: np.ndarray | None, w_inv_b: np.ndarray, wp: np.ndarray
    ) -> np.ndarray:
        """The Jacobian rows, weighted: ``w`` (None for 1), ``w_inv_b`` = w/b and ``wp`` = w·p
        before softening.

        ∂p/∂kc = w·S·z^n'/b, ∂p/∂kφ = w·S·z^n', ∂p/∂k = w·S·z^n' (Bernstein), ∂p/∂n = w·p·ln z,
        ∂p/∂s_i = w·p·F_i, ∂p/∂d_i = w·p·ln z·G_i (n' = n + D); softened samples below.
        """
        lay = self.layout
        _, scale, expo, zn, k_eff, p, soft = self._parts_at(theta)
        out = np.empty((self.size, zn.size))
        zs = zn if scale is None else zn * scale
        if lay.bekker:
            np.multiply(zs, w_inv_b, out=out[0])
            if w is None:
                out[1] = zs
            else:
                np.multiply(zs, w, out=out[1])
            i = 2
        else:
            if w is None:
                out[0] = zs
            else:
                np.multiply(zs, w, out=out[0])
            i = 1
        i_n = i
        np.multiply(wp, self.lnz, out=out[i_n])
        i += 1
        for row in range(lay.n_s):
            np.multiply(wp, self.fs_rows[row], out=out[i])
            i += 1
        for row in range(lay.n_d):
            np.multiply(out[i_n], self.gd_rows[row], out=out[i])
            i += 1
        if soft is not None:
            self._soften_rows(out, i, w, scale, expo, k_eff, p, soft)
        return out

    def _soften_rows(
        self,
        out: np.ndarray,
        i: int,
        w: np.ndarray | None,
        scale: np.ndarray | None,
        expo: np.ndarray,
        k_eff: np.ndarray,
        p: np.ndarray,
        soft: tuple,
    ) -> None:
        """Rows of the softened samples (Fig. 9's two-stage law), weighted by ``w``.

        Beyond z_c, p = p(z_c) + f·(p − p(z_c)), so each base and covariate row becomes
        (1 − f)·∂p(z_c)/∂θ + f·∂p/∂θ there, and ∂p/∂z_c = (1 − f)·p(z_c)·n'/z_c,
        ∂p/∂f = p − p(z_c); elsewhere the rows stay and those of z_c and f are 0.  Only the
        softened samples are computed.
        """
        lay = self.layout
        zc, frac, lzc, pc, beyond = soft
        idx = np.flatnonzero(beyond)
        out[i : i + 2] = 0.0
        if not idx.size:
            return

        def at(a):  # a per-sample array at the softened samples (a scalar as it is)
            return a[idx] if np.ndim(a) else a

        wi = 1.0 if w is None else w[idx]
        pc_i, k_i = at(pc), at(k_eff)
        zcn = pc_i / np.where(k_i != 0, k_i, 1.0)
        zcs = zcn if scale is None else zcn * scale[idx]
        # w·∂p(z_c)/∂θ for the base and covariate parameters, in the order of the rows.
        ccols = [zcs * self.inv_b[idx] * wi, zcs * wi] if lay.bekker else [zcs * wi]
        pc_lzc = pc_i * lzc * wi
        ccols.append(pc_lzc)
        ccols += [pc_i * self.fs_rows[r, idx] * wi for r in range(lay.n_s)]
        ccols += [pc_lzc * self.gd_rows[r, idx] for r in range(lay.n_d)]
        for row, cc in enumerate(ccols):
            out[row, idx] = (1 - frac) * cc + frac * out[row, idx]
        out[i, idx] = (1 - frac) * pc_i * at(expo) / zc * wi
        out[i + 1, idx] = (p[idx] - pc_i) * wi


#: The extended pressure–sinkage family (:class:`SinkageFamily`, the same arguments);
#: ``f, jac = family``.
sinkage_family = SinkageFamily


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


class ShearFamily(_Family):
    """The extended Janosi–Hanamoto family over fixed σ [Pa] and j [m]; τ in Pa, K in m.

    Covariate factors and side walls combine: τ = (c·S_c·(1 + a) + σ·tan φ·S_t·(1 + a·K0))·
    (1 − exp(−j/(K·S_K))), with the wall terms only when ``layout.side_walls``.
    """

    def __init__(
        self,
        layout: ShearLayout,
        sigma: ArrayLike,
        j: ArrayLike,
        fc: ArrayLike | None = None,
        ft: ArrayLike | None = None,
        fk: ArrayLike | None = None,
        a: ArrayLike | None = None,
    ) -> None:
        super().__init__()
        self.layout = layout
        self.size = layout.size
        self.sigma = np.asarray(sigma, float)
        self.j = np.asarray(j, float)
        self.fc_rows, self.ft_rows, self.fk_rows = (_rows_of(m) for m in (fc, ft, fk))
        self.fc_times, self.ft_times, self.fk_times = (_product_of(m) for m in (fc, ft, fk))
        # Side-wall ratios; None (never read) without side walls.
        self.a: Any = None if a is None else np.asarray(a, float)
        self.i_c = 3
        self.i_t = 3 + layout.n_c
        self.i_k = 3 + layout.n_c + layout.n_t
        self.i_end = self.i_k + layout.n_k

    def _compute(self, theta):
        lay = self.layout
        c, phi, k = theta[0], theta[1], theta[2]
        t = np.tan(phi * RAD_PER_DEG)
        # S = None stands for a factor of exactly 1 (no term): the products with it are
        # skipped, which changes no bit of the result.
        s_c = np.exp(self.fc_times(theta[self.i_c : self.i_t])) if lay.n_c else None
        s_t = np.exp(self.ft_times(theta[self.i_t : self.i_k])) if lay.n_t else None
        if lay.side_walls:
            s_c = 1.0 + self.a if s_c is None else s_c * (1.0 + self.a)
            s_t = 1.0 + self.a * theta[-1] if s_t is None else s_t * (1.0 + self.a * theta[-1])
        k_eff = k * np.exp(self.fk_times(theta[self.i_k : self.i_end])) if lay.n_k else k
        decay = np.exp(-self.j / k_eff)
        g = 1.0 - decay
        c_s = c if s_c is None else c * s_c
        st = self.sigma * t
        st_s = st if s_t is None else st * s_t
        level = c_s + st_s
        return c, t, phi, s_c, s_t, k_eff, decay, g, c_s, st_s, level

    def value(self, theta: np.ndarray) -> np.ndarray:
        *_, g, _, _, level = self._parts_at(theta)
        return level * g

    def rows(self, theta: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
        """(p, N) rows of ∂τ/∂θ, times the weights ``w`` when given."""
        lay = self.layout
        _, _, phi, s_c, s_t, k_eff, decay, g, c_s, st_s, level = self._parts_at(theta)
        out = np.empty((self.size, g.size))
        if s_c is None:
            out[0] = g
        else:
            np.multiply(s_c, g, out=out[0])
        sig_s = self.sigma if s_t is None else self.sigma * s_t
        np.multiply(sig_s * RAD_PER_DEG / np.cos(phi * RAD_PER_DEG) ** 2, g, out=out[1])
        dk_eff = -level * decay * self.j / k_eff**2  # ∂τ/∂K_eff
        dk_k = dk_eff * k_eff
        np.divide(dk_k, theta[2], out=out[2])
        i = 3
        for row in range(lay.n_c):
            np.multiply(c_s * self.fc_rows[row], g, out=out[i])
            i += 1
        for row in range(lay.n_t):
            np.multiply(st_s * self.ft_rows[row], g, out=out[i])
            i += 1
        for row in range(lay.n_k):
            np.multiply(dk_k, self.fk_rows[row], out=out[i])
            i += 1
        if lay.side_walls:
            # ∂/∂K0 of σ·tan φ·S_t·(1 + a·K0): S_t without its wall factor, times a.
            np.multiply(st_s / (1.0 + self.a * theta[-1]) * self.a, g, out=out[i])
        if w is not None:
            out *= w
        return out


#: The extended Janosi–Hanamoto family (:class:`ShearFamily`, the same arguments);
#: ``f, jac = family``.
shear_family = ShearFamily


class ModelFamily(_Family):
    """Any :class:`Model` with covariate terms over fixed inputs ``x`` (module docstring):
    y = S·f(x, θ'), S = exp(F·s) per sample, θ' the model's parameters with ``offset``
    (its exponent n) moved by G·d per sample.  θ = (model parameters, s, d).

    The model's ``func`` and ``jac`` are evaluated with that parameter as a per-sample array,
    so they must broadcast (numpy expressions do).  ∂y/∂θ_model = S·∂f/∂θ', ∂y/∂s_i = y·F_i,
    ∂y/∂d_i = S·∂f/∂θ'_offset·G_i.
    """

    def __init__(
        self,
        model: Model,
        x: ArrayLike,
        fs: ArrayLike | None = None,
        gd: ArrayLike | None = None,
        offset: str | None = None,
    ) -> None:
        super().__init__()
        self.base = model
        self.x = x
        self.p = model.n_params
        self._scale_and_offset_features(fs, gd)
        self.n_s = 0 if fs is None else self.fs_rows.shape[0]
        self.n_d = 0 if gd is None else self.gd_rows.shape[0]
        if self.n_d and offset not in model.param_names:
            raise ModelError(f"{model.name}: an offset needs a parameter to move, got {offset!r}")
        # The offset parameter's index; None (never read) without offset features.
        self.i_off: Any = model.param_names.index(offset) if self.n_d else None
        self.size = self.p + self.n_s + self.n_d

    def _output(self) -> str:
        return self.base.output

    def _compute(self, theta):
        p, n_s = self.p, self.n_s
        params = [theta[i] for i in range(p)]
        if self.n_d:
            params[self.i_off] = theta[self.i_off] + self.gd_times(theta[p + n_s :])
        f0 = np.asarray(self.base.func(self.x, *params), float)
        jac0 = np.asarray(self.base.jac(self.x, *params), float).reshape(f0.size, p)
        scale = np.exp(self.fs_times(theta[p : p + n_s])) if n_s else None
        return scale, jac0, f0 if scale is None else f0 * scale

    def value(self, theta: np.ndarray) -> np.ndarray:
        return self._parts_at(theta)[2]

    def rows(self, theta: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
        """(size, N) rows of ∂y/∂θ, times the weights ``w`` when given."""
        scale, jac0, value = self._parts_at(theta)
        p = self.p
        out = np.empty((self.size, value.size))
        out[:p] = jac0.T if scale is None else jac0.T * scale
        i = p
        for row in range(self.n_s):
            np.multiply(value, self.fs_rows[row], out=out[i])
            i += 1
        for row in range(self.n_d):
            np.multiply(out[self.i_off], self.gd_rows[row], out=out[i])
            i += 1
        if w is not None:
            out *= w
        return out


def model_family(
    model: Model,
    x: ArrayLike,
    fs: ArrayLike | None = None,
    gd: ArrayLike | None = None,
    offset: str | None = None,
) -> ModelFamily:
    """The generic extended family of a model (:class:`ModelFamily`); ``f, jac = family``."""
    return ModelFamily(model, x, fs, gd, offset)

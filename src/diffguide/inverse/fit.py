r"""Rail profiles from measured joint kinematic errors: regularised Levenberg–Marquardt through the
differentiable machine model (SPEC §2.5).

Residuals, one per merged measurement ``i`` in channel ``c(i)`` (a point and a quantity):

.. math::  r_i(θ) = \bigl(m_i(Zθ) - y_i - o_{c(i)}\bigr)/σ_i,

``m_i`` the model's joint error (:func:`diffguide.kinematics.joint_errors`, the equilibrium
differentiated implicitly), ``o_c`` the channel's zero — every instrument reads relative to its
own zero, so each channel's weighted mean misfit is profiled out (this also makes the fit
independent of ``x_ref``). The fit minimises

.. math::  ‖r(θ)‖² + λ\,‖G Z θ‖²,

(``‖G c‖² = Σ∫e''² ds + ℓ⁻⁴Σ∫e² ds``, see :mod:`.basis`) with
``optimistix.LevenbergMarquardt`` on the
stacked residual vector, started from the Gauss–Newton step at ``θ = 0`` (the model is nearly
linear in the µm-sized rail errors).

Regularisation weight — **generalised cross-validation** (GCV; Craven & Wahba 1979):
``λ = argmin N'‖r_λ‖²/(N' − tr A_λ)²`` on the problem linearised at the current estimate, ``A``
the influence matrix and ``N'`` the data count less the channel zeros; re-evaluated at the
solution and refitted once if it moved. Why GCV: (1) it needs no knowledge of σ — the
discrepancy principle trusts the σ column fully, and a 20 % error in the stated repeatability
moves its λ by orders of magnitude, while GCV still works when σ comes from a handful of runs;
(2) with the penalty read as a Gaussian smoothness prior, the posterior bands at the GCV weight
have close to nominal coverage *averaged over the profile* (Wahba 1983; Nychka 1988,
J. Am. Stat. Assoc. 83, 1134), which is the use made of the bands here; (3) the L-curve has no
such property and its corner is ill defined for slowly decaying singular values like ours.

Posterior covariance (Gauss–Newton, the Bayesian reading of the penalty):
``Cov θ = (J̃ᵀJ̃ + λ ZᵀGᵀGZ)⁻¹``, ``J̃ = ∂r/∂θ`` (jacfwd through the implicit equilibrium).
``χ²/dof = ‖r‖²/(N − n_channels − tr A)``.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._precision import require_x64
from ..kinematics import joint_errors
from ..machine import Machine
from ..measurements import QUANTITIES, Measurements
from ..rails import SplineRail
from .basis import RailBasis, null_space_basis

_UM = 1e-6


class _Problem(eqx.Module):
    """Everything the residual needs; arrays travel as arguments (never closed over)."""

    machine: Machine
    basis: RailBasis
    positions: jax.Array
    pos_idx: jax.Array
    pt_idx: jax.Array
    q_idx: jax.Array
    value: jax.Array
    sigma: jax.Array
    chan: jax.Array
    n_chan: int = eqx.field(static=True)
    x_ref: jax.Array


def _rails(c_um, basis: RailBasis):
    c = c_um.reshape(2, 2, basis.n_coeffs) * _UM
    return tuple(SplineRail(basis.start, basis.spacing, c[r, 0], c[r, 1]) for r in range(2))


def _model(c_um, prob: _Problem):
    """Model values (SI) at every merged measurement and whether every equilibrium converged;
    ``c_um``: the stacked spline coefficients (µm)."""
    je = joint_errors(prob.machine, _rails(c_um, prob.basis), prob.positions, prob.x_ref)
    return je.errors[prob.pos_idx, prob.pt_idx, prob.q_idx], jnp.all(je.converged)


def _data_residual(c_um, prob: _Problem):
    return _data_residual_full(c_um, prob)[0]


def _data_residual_full(c_um, prob: _Problem):
    """Whitened residuals with the channel zeros profiled out, model values, convergence."""
    pred, ok = _model(c_um, prob)
    d = pred - prob.value
    w = 1.0 / prob.sigma**2
    off = jax.ops.segment_sum(w * d, prob.chan, prob.n_chan) / jax.ops.segment_sum(
        w, prob.chan, prob.n_chan)
    return (d - off[prob.chan]) / prob.sigma, pred, ok


def _residual_and_jacobian(theta, Z, prob: _Problem):
    """``r(Zθ)`` and ``∂r/∂θ`` (forward mode only: PITFALLS, never jacrev)."""
    J, r = jax.jacfwd(lambda t: (_data_residual(Z @ t, prob),) * 2, has_aux=True)(theta)
    return r, J


@eqx.filter_custom_jvp
def _data_residual_lm(theta, Z, prob: _Problem):
    """:func:`_data_residual` whose JVP is ``J·dθ`` with ``J`` built in the primal pass.

    LevenbergMarquardt linearises its residual once per step and, at step 0, queries a
    zero-filled placeholder of that linearisation. Through the plain model the placeholder
    reaches the equilibrium's implicit linear solve as a zero operator, which raises
    ("non-finite input", ../shared/PITFALLS.md); here the linearisation holds only the matrix
    ``J``, and a zero ``J`` is harmless. The cost is the same: LM materialises ``J`` anyway.
    """
    return _data_residual(Z @ theta, prob)


@_data_residual_lm.def_jvp
def _data_residual_lm_jvp(primals, tangents):
    theta, Z, prob = primals
    dtheta = tangents[0]
    r, J = _residual_and_jacobian(theta, Z, prob)
    return r, (jnp.zeros_like(r) if dtheta is None else J @ dtheta)


def _lm_residual(theta, args):
    prob, Z, GZ, sqrt_lam = args
    return jnp.concatenate([_data_residual_lm(theta, Z, prob), sqrt_lam * (GZ @ theta)])


@eqx.filter_jit
def _linearise(c_um, prob: _Problem):
    """Residual, Jacobian w.r.t. all coefficients ``c`` (µm), model values, convergence."""

    def f(c):
        r, pred, ok = _data_residual_full(c, prob)
        return r, (r, pred, ok)

    J, (r, pred, ok) = jax.jacfwd(f, has_aux=True)(c_um)
    return r, J, pred, ok


@eqx.filter_jit
def _lm(theta0, args, rtol, atol, max_steps: int):
    solver = optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    sol = optx.least_squares(
        _lm_residual, solver, theta0, args=args, max_steps=max_steps, throw=False,
    )
    return sol.value, sol.result == optx.RESULTS.successful, sol.stats["num_steps"]


def gcv_weight(J, r, Omega, n_eff: int, lam_grid=None):
    """GCV over λ for the linear problem ``min ‖J δ + r‖² + λ (θ+δ)ᵀΩ(θ+δ)`` at ``θ = 0``.

    Returns ``(λ, score, table)`` with ``table`` the ``(λ, GCV)`` pairs tried.
    """
    M = J.T @ J
    g = J.T @ r
    if lam_grid is None:
        lam0 = np.trace(M) / max(np.trace(Omega), 1e-300)
        lam_grid = lam0 * np.logspace(-14, 4, 73)

    def score(lam):
        H = M + lam * Omega
        try:
            delta = -np.linalg.solve(H, g)
            tr = np.trace(np.linalg.solve(H, M))
        except np.linalg.LinAlgError:
            return np.inf
        res = r + J @ delta
        return n_eff * (res @ res) / max(n_eff - tr, 1e-9) ** 2

    scores = np.array([score(lam) for lam in lam_grid])
    k = int(np.argmin(scores))
    lo, hi = lam_grid[max(k - 1, 0)], lam_grid[min(k + 1, len(lam_grid) - 1)]
    fine = np.geomspace(lo, hi, 17)
    fs = np.array([score(lam) for lam in fine])
    j = int(np.argmin(fs))
    table = np.concatenate([np.stack([lam_grid, scores], 1), np.stack([fine, fs], 1)])
    return float(fine[j]), float(fs[j]), table[np.argsort(table[:, 0])]


class RailFit(eqx.Module):
    """Result of :func:`fit_rails` (SI unless stated).

    Attributes:
        basis: the knot grid. coeffs: ``(2 rails, 2 planes, n)`` spline coefficients (m),
            planes ``(vertical, horizontal)``. cov: posterior covariance of the stacked
            coefficients (order of :data:`~.basis.PROFILES`; m²).
        Z: the gauge-fixed parametrisation (``c = Z θ``). gauge: names of the fixed modes.
        fix_slope: which planes have the common slope fixed.
        lam: regularisation weight (GCV). gcv: its score. lam_table: ``(λ, GCV)`` tried.
        fitted: model at every merged measurement, shifted by its channel zero (m or rad).
        residual: measured − fitted. offsets: each channel's zero (model − measured).
        chi2, dof, edf: χ², degrees of freedom ``N − n_channels − edf``, effective parameters.
        converged: LM and every equilibrium converged. steps: LM steps (all outer passes).
        jacobian: whitened data Jacobian ``∂r/∂θ`` at the solution; jacobian_full: the same
            w.r.t. all coefficients ``c`` (µm), gauge modes included. Omega: ``ZᵀGᵀGZ``.
        rigid: fitted with the rigid-table model.
    """

    basis: RailBasis
    coeffs: np.ndarray
    cov: np.ndarray
    Z: np.ndarray
    gauge: tuple[str, ...] = eqx.field(static=True)
    fix_slope: tuple[bool, bool] = eqx.field(static=True)
    lam: float
    gcv: float
    lam_table: np.ndarray
    fitted: np.ndarray
    residual: np.ndarray
    offsets: np.ndarray
    chi2: float
    dof: float
    edf: float
    converged: bool
    steps: int
    jacobian: np.ndarray
    jacobian_full: np.ndarray
    Omega: np.ndarray
    rigid: bool = eqx.field(static=True)

    @property
    def chi2_dof(self) -> float:
        return self.chi2 / self.dof

    def profiles(self, s) -> tuple[np.ndarray, np.ndarray]:
        """Profiles and their posterior σ at ``s`` (m): two ``(2 rails, 2 planes, len(s))``
        arrays (m)."""
        B = self.basis.matrix(s)
        n = self.basis.n_coeffs
        val = np.einsum("sk,rpk->rps", B, self.coeffs)
        sig = np.zeros_like(val)
        for k in range(4):
            r, p = divmod(k, 2)
            C = self.cov[k * n:(k + 1) * n, k * n:(k + 1) * n]
            sig[r, p] = np.sqrt(np.maximum(np.einsum("sk,kl,sl->s", B, C, B), 0.0))
        return val, sig

    def rails(self) -> tuple[SplineRail, SplineRail]:
        """The fitted profiles as :class:`~diffguide.rails.SplineRail` (rail 1, rail 2)."""
        c = self.coeffs
        return tuple(SplineRail(self.basis.start, self.basis.spacing, jnp.asarray(c[r, 0]),
                                jnp.asarray(c[r, 1])) for r in range(2))


def visited_range(machine: Machine, positions) -> tuple[float, float]:
    """Rail length ``[lo, hi]`` (m) the rolling elements visit over ``positions`` (m) and x = 0."""
    x = np.concatenate([np.asarray(positions, float), [0.0]])
    xc = np.asarray(machine.carriage_x, float)
    xi = np.asarray(machine.carriage.xi, float)
    return float(x.min() + xc.min() + xi.min()), float(x.max() + xc.max() + xi.max())


def _problem(machine, meas: Measurements, basis, x_ref):
    positions, pos_idx = np.unique(np.round(meas.position, 9), return_inverse=True)
    chan = meas.channel_index()
    return _Problem(
        machine=machine, basis=basis, positions=jnp.asarray(positions),
        pos_idx=jnp.asarray(pos_idx), pt_idx=jnp.asarray(meas.point),
        q_idx=jnp.asarray(meas.quantity), value=jnp.asarray(meas.value),
        sigma=jnp.asarray(meas.sigma), chan=jnp.asarray(chan), n_chan=int(chan.max()) + 1,
        x_ref=jnp.asarray(float(x_ref)),
    )


def fit_rails(
    machine: Machine,
    meas: Measurements,
    *,
    knot_spacing: float | None = None,
    lam: float | None = None,
    x_ref: float = 0.0,
    rtol: float = 1e-5,
    atol: float = 1e-5,
    max_steps: int = 40,
    method: str = "lm",
) -> RailFit:
    """Fit the rail straightness profiles to merged measurements (see the module docstring).

    Arguments:
        machine: the machine model whose points are ``meas.point_names`` (same order);
            ``machine.with_rigid_table()`` gives the classical rigid-table inversion.
        meas: merged measurements (:func:`diffguide.measurements.read_measurements`).
        knot_spacing: requested knot spacing (m); default the carriage's loaded length
            (``n·p``, 48 mm for ``majda2012``): shorter wavelengths are averaged out by the
            carriage (``H_z`` has its first zero at ``λ = n·p``), so finer knots only add
            undetermined unknowns. The actual spacing divides the visited length evenly.
        lam: regularisation weight; default GCV (module docstring).
        x_ref: reference position of the model (m); the result does not depend on it.
        rtol, atol: LM tolerances (θ in µm, residuals whitened). max_steps: LM step limit.
        method: ``"lm"`` (Levenberg–Marquardt through the nonlinear model) or ``"linear"``
            (the model linearised at straight rails, solved once: the classical linear
            inversion, used for the rigid-table alternative).
    """
    if method not in ("lm", "linear"):
        raise ValueError(f"method must be 'lm' or 'linear', got {method!r}")
    require_x64("fit_rails")
    if tuple(machine.point_names) != tuple(meas.point_names):
        raise ValueError(
            f"the machine's points {machine.point_names} differ from the measurement points "
            f"{meas.point_names}; build the machine with points=... from the measurements"
        )
    if knot_spacing is None:
        knot_spacing = machine.carriage.length
    lo, hi = visited_range(machine, meas.position)
    basis = RailBasis.covering(lo, hi, knot_spacing)
    q = {QUANTITIES[k] for k in np.unique(meas.quantity)}
    fix_slope = ("EZX" not in q, "EYX" not in q)
    C, gauge = basis.gauge_functionals(fix_slope)
    Z = null_space_basis(C, basis.size)
    G = np.concatenate([basis.penalty_factor(), basis.amplitude_factor()])
    GZ = G @ Z
    Omega = GZ.T @ GZ
    prob = _problem(machine, meas, basis, x_ref)
    n_eff = meas.n - prob.n_chan
    if n_eff <= 0:
        raise ValueError(f"{meas.n} measurements in {prob.n_chan} channels: nothing to fit")

    theta = np.zeros(Z.shape[1])
    r, Jc, _, ok = (np.asarray(v) for v in _linearise(jnp.zeros(basis.size), prob))
    J = Jc @ Z
    if not ok:
        raise ValueError("the machine equilibrium did not converge for straight rails")
    fixed = lam is not None
    table = np.zeros((0, 2))
    score = float("nan")
    if not fixed:
        lam, score, table = gcv_weight(J, r, Omega, n_eff)
    theta = -np.linalg.solve(J.T @ J + lam * Omega, J.T @ r)  # Gauss–Newton start
    steps, converged = 0, True
    pred = np.full(meas.n, np.nan)  # the model at the solution (LM only)
    for _ in range(2 if method == "lm" else 0):
        # LM works on φ with θ = T φ, T = L⁻ᵀ from the Cholesky factor of the Gauss–Newton
        # Hessian: isotropic damping then suits every direction (the Hessian's eigenvalues span
        # ~10 decades, and LM with identity damping crawls along the small ones).
        T = _preconditioner(J.T @ J + lam * Omega)
        args = (prob, jnp.asarray(Z @ T), jnp.asarray(GZ @ T), jnp.asarray(np.sqrt(lam)))
        phi0 = np.linalg.solve(T, theta)
        value, lm_ok, n = _lm(jnp.asarray(phi0), args, rtol, atol, max_steps)
        theta, steps, converged = T @ np.asarray(value), steps + int(n), bool(lm_ok)
        r, Jc, pred, ok = (np.asarray(v) for v in _linearise(jnp.asarray(Z @ theta), prob))
        J = Jc @ Z
        converged = converged and bool(ok)
        if fixed:
            break
        # GCV again, linearised at the solution (the penalty acts on the total θ)
        new_lam, score, table = _gcv_at(J, r, theta, Omega, n_eff)
        if abs(np.log(new_lam / lam)) < np.log(1.5):
            lam = new_lam
            break
        lam = new_lam
    if method == "linear":  # residuals of the linear model at the solution
        r = r + J @ theta
    H = J.T @ J + lam * Omega
    cov_theta = np.linalg.inv(H)
    cov_theta = 0.5 * (cov_theta + cov_theta.T)
    edf = float(np.trace(cov_theta @ (J.T @ J)))
    chi2 = float(r @ r)
    sigma = np.asarray(meas.sigma)
    residual = -r * sigma  # measured − fitted, with the channel zero profiled out
    fitted = np.asarray(meas.value) - residual
    offsets = np.array([np.nan] * prob.n_chan)
    chan = np.asarray(prob.chan)
    for c in range(prob.n_chan):
        sel = chan == c
        offsets[c] = np.mean((pred - fitted)[sel])  # NaN for the linear method
    c_um = Z @ theta
    cov = Z @ cov_theta @ Z.T * _UM**2
    return RailFit(
        basis=basis, coeffs=(c_um * _UM).reshape(2, 2, basis.n_coeffs), cov=cov, Z=Z,
        gauge=tuple(gauge), fix_slope=fix_slope, lam=float(lam), gcv=float(score),
        lam_table=table, fitted=fitted, residual=residual, offsets=offsets, chi2=chi2,
        dof=float(n_eff - edf), edf=edf, converged=converged, steps=steps, jacobian=J,
        jacobian_full=Jc,
        Omega=Omega, rigid=bool(machine.rigid),
    )


def _preconditioner(H):
    """``T`` with ``Tᵀ H T = I`` (``L⁻ᵀ`` of the Cholesky factor; eigenvalues if that fails)."""
    try:
        L = np.linalg.cholesky(H)
        return np.linalg.inv(L).T
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(0.5 * (H + H.T))
        w = np.maximum(w, 1e-12 * w.max())
        return V / np.sqrt(w)


def _gcv_at(J, r, theta, Omega, n_eff):
    """GCV for the Gauss–Newton step from ``theta``: the penalty acts on ``θ + δ``."""
    # shift to a problem in the total unknown: data residual r + J δ = (r − Jθ) + J θ_total
    r0 = r - J @ theta
    return gcv_weight(J, r0, Omega, n_eff)

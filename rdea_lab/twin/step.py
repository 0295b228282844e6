"""`TwinStep`: the twin one sample at a time, for a control loop (no allocation per call)."""

from __future__ import annotations

import numpy as np

from ..physics.models import MODELS, solve
from ..physics.result import BAD_INPUT, PathEnd
from ..specs import as_params
from .simulate import as_geometry, viscous

#: What `TwinStep.step` returns, by index.
FIELDS = ("force", "capacitance", "sigma1", "sigma1_irr", "lambda2b", "model_status")
FORCE, CAPACITANCE, SIGMA1, SIGMA1_IRR, LAMBDA2B, MODEL_STATUS = range(6)


class TwinStep:
    """The twin (a quasi-static model, its branches and the force) advanced one sample per call.

    The same numbers as `TwinStream` / `simulate` over the whole series, to
    rounding (tested to 1e-12), except ``eta_v0``'s rate at the very first
    sample, which a stepper cannot know yet and takes as 0 (the series takes
    the first interval's slope). Each call is one compiled function
    (:mod:`rdea_lab.physics.step_kernel`) on preallocated state. 1R and 3R samples stay compiled however
    hard (folds, snaps, pull-in, the range's end, slack: the reference's full scan and path rule compiled,
    `rdea_lab.physics.scan_kernel`), a few microseconds, at most a few hundred on a landscape with folds;
    a CR sample of a roll with a core, a NaN stretch and a stretch below 1 are solved by the reference
    solver from the same state (milliseconds). The
    reference grades its scan near a small core to the largest span of the block it solves, so where a
    fold hides between its nodes the label can depend on how the series is cut into blocks: there a
    stepped run can differ from a whole-series run, as two block sizes already could.

    Parameters
    ----------
    specimen : SpecimenCard, RollGeometry or path
        The roll (a card's path is read).
    params : ParameterSet or path
        The material: Yeoh ``C10, C20, C30`` [Pa], ``eps_r`` [-], the Maxwell branches and ``eta_v0``.
    model : {"su", "1r", "3r", "cr"}
        Quasi-static model, Sections 3.1-3.3 of [1].

    Raises
    ------
    ValueError
        An unknown ``model``, or one that does not apply to the roll.
    SpecError
        A card or parameter file that cannot be read.
    rdea_lab.extras.MissingExtra
        numba is not installed (``pip install rdea-lab[fast]``).

    Notes
    -----
    The force of eqs. (43), (44) and (16) of [1], as `simulate` computes it.

    References
    ----------
    [1] J. Prechtl, J. Kunze, G. Moretti, D. Bruch, S. Seelecke, G. Rizzello, "Modeling and experimental
        validation of thin, tightly rolled dielectric elastomer actuators", Smart Mater. Struct. 31 (2022)
        015008 (2021 online), doi:10.1088/1361-665X/ac34be.

    Examples
    --------
    >>> twin = TwinStep("specimens/specimen2.yaml", "params/paper2021_table3.yaml", "su")  # doctest: +SKIP
    >>> out = twin.step(0.0, 1.2, 2600.0)      # out[FORCE] [N], out[CAPACITANCE] [F], ...  # doctest: +SKIP
    """

    def __init__(self, specimen, params, model="su"):
        from ..extras import require

        require("numba", "TwinStep (the compiled per-sample step)")
        from ..physics import step_kernel  # numba: loaded here, not at the first step

        if model not in MODELS:
            raise ValueError(f"model {model!r}; allowed: {', '.join(MODELS)}")
        self.geom = as_geometry(specimen)
        self.params = as_params(params)
        self.model = model
        solve(model, self.geom, self.params, np.array([1.0]), np.array([0.0]))  # applicable to this geometry?
        k, eta, eta_v0, law = viscous(self.params)
        self._code, self._P, self._R, self._B, self._offsets, self._pitchfork = step_kernel.constants(
            model, self.geom, self.params, k, eta / k, eta_v0, law)
        self._S = np.zeros(step_kernel.Q_START + k.size)
        self._out = np.full(len(FIELDS), np.nan)
        self._kernel = step_kernel.step
        self._advance = step_kernel.advance
        self._time_error = step_kernel.TIME_NOT_INCREASING

    def reset(self) -> None:
        """Back to the unloaded, relaxed roll before its first sample."""
        self._S[:] = 0.0
        self._out[:] = np.nan

    def step(self, t, stretch, voltage) -> np.ndarray:
        """Advance to time ``t`` [s] at ``stretch`` [-] and ``voltage`` [V].

        Parameters
        ----------
        t : float
            Time of the sample [s], after the previous one's.
        stretch : float
            Axial stretch [-]; NaN gives a NaN sample (status ``NaN input``) and the branches carry on.
        voltage : float
            Voltage [V].

        Returns
        -------
        numpy.ndarray, shape (6,)
            ``force`` [N], ``capacitance`` [F], ``sigma1``, ``sigma1_irr`` [Pa],
            ``lambda2b`` [-], ``model_status`` (indices `FORCE` ... `MODEL_STATUS`);
            the same array every call, overwritten by the next.

        Raises
        ------
        ValueError
            ``t`` is not finite or not after the previous sample's time.
        """
        r = self._kernel(self._code, self._S, self._P, self._R, self._B, self._offsets, self._pitchfork, t, stretch,
                         voltage, self._out)
        if r == 0:
            return self._out
        if r == self._time_error:
            if not np.isfinite(t):
                raise ValueError(f"t = {t!r}: the time must be finite")
            raise ValueError(f"t = {t!r} is not after the previous sample's {self._S[1]!r}")
        return self._reference(float(t), float(stretch), float(voltage))

    def _reference(self, t, stretch, voltage):
        S, out = self._S, self._out
        if not np.isfinite(stretch):  # no state: the branches carry on across it (as in a series)
            out[:] = np.nan
            out[MODEL_STATUS] = BAD_INPUT
            return out
        start = None
        if S[0] != 0.0:
            label = None if S[4] != 0.0 else (int(S[5]), float(S[6]))
            start = PathEnd(self.model, None if np.isnan(S[3]) else float(S[3]), label)
        res = solve(self.model, self.geom, self.params, np.array([stretch]), np.array([voltage]), path=True,
                    start=start)
        self._advance(S, self._P, t, stretch, float(res.tension[0]), float(res.capacitance[0]),
                      float(res.lambda2b[0]), int(res.status[0]), out)
        y = res.end.y
        S[3] = np.nan if y is None else y
        label = res.end.label
        S[4] = 1.0 if label is None else 0.0
        S[5], S[6] = (0.0, np.nan) if label is None else label
        return out

"""Integrators ``hht-alpha`` and ``newmark``: the structural-dynamics members of the family.

Both are the generalized-alpha step of :mod:`.generalized_alpha` (Arnold & Bruls 2007, on
the index-3 mechanical form) with the parameters (alpha_m, alpha_f, beta, gamma) their
authors chose, named as structural-dynamics users know them:

* **HHT-alpha** (H. M. Hilber, T. J. R. Hughes, R. L. Taylor, "Improved numerical
  dissipation for time integration algorithms in structural dynamics", Earthquake Eng.
  Struct. Dyn. 5 (1977) 283-292): option ``alpha`` in [-1/3, 0] (their sign), giving
  alpha_m = 0, alpha_f = -alpha, gamma = 1/2 - alpha, beta = (1 - alpha)^2 / 4. Second
  order; spectral radius at infinity rho_inf = (1 + alpha) / (1 - alpha) (1/2 at
  alpha = -1/3). The default -0.05 is the usual light damping of high frequencies.
* **Newmark** (N. M. Newmark, "A method of computation for structural dynamics", J. Eng.
  Mech. Div. ASCE 85 (1959) 67-94): options ``gamma`` >= 1/2 and ``beta`` > 0, giving
  alpha_m = alpha_f = 0. Second order only at gamma = 1/2 (the default, with beta = 1/4:
  the average-acceleration or trapezoidal rule, no numerical damping, rho_inf = 1);
  gamma > 1/2 damps and is first order. Unconditionally stable for 2 beta >= gamma. With
  rho_inf = 1 the multipliers of an index-3 system are not damped: Cardona and Geradin
  (1989) found the trapezoidal rule unstable on index-3 mechanism equations, which is why
  HHT and generalized-alpha exist; compare them here. Measured on the slider-crank
  (tests/test_hht_newmark.py's setting, steps 4e-3 to 5e-4 s): position order 1.6 for
  the average-acceleration rule where HHT-alpha gives 2.

Step size, adaptivity and Newton's method are those of ``generalized-alpha``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from workbench.errors import ConfigError
from workbench.plugin.registry import integrator
from workbench.plugins.integrators.generalized_alpha import GeneralizedAlpha, StepOptions


@dataclass(frozen=True)
class HhtOptions(StepOptions):
    alpha: float = -0.05  # in [-1/3, 0]; 0 is the trapezoidal rule

    def __post_init__(self) -> None:
        super().__post_init__()
        if not -1.0 / 3.0 <= self.alpha <= 0.0:
            raise ConfigError(f"alpha must lie in [-1/3, 0] (HHT's sign), not {self.alpha}")


@dataclass(frozen=True)
class NewmarkOptions(StepOptions):
    gamma: float = 0.5  # >= 1/2; > 1/2 damps and is first order
    beta: float = 0.25  # > 0; unconditionally stable for 2 beta >= gamma

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.gamma >= 0.5:
            raise ConfigError(f"gamma must be >= 1/2 (below it Newmark is unstable): {self.gamma}")
        if not 0.0 < self.beta <= 0.5:
            raise ConfigError(f"beta must lie in (0, 1/2], not {self.beta}")


@integrator
class HhtAlpha(GeneralizedAlpha):
    name = "hht-alpha"
    summary = "HHT-alpha (Hilber-Hughes-Taylor 1977) on the index-3 form: alpha_m = 0"
    Options = HhtOptions

    @staticmethod
    def parameters(options: Any) -> tuple[float, float, float, float]:
        alpha = options.alpha
        return 0.0, -alpha, 0.25 * (1.0 - alpha) ** 2, 0.5 - alpha


@integrator
class Newmark(GeneralizedAlpha):
    name = "newmark"
    summary = "Newmark (1959) beta-gamma on the index-3 form; default average acceleration"
    Options = NewmarkOptions

    @staticmethod
    def parameters(options: Any) -> tuple[float, float, float, float]:
        return 0.0, 0.0, options.beta, options.gamma

"""The time laws' shared tuning: margins below the limits and the dense limit check.

One place for the numbers every law that samples its result uses (:mod:`.smoothing`, :mod:`.jerk`,
:mod:`.constant_speed`, :mod:`.parameterize`); each law's own tuning stays in its module.
"""
from __future__ import annotations

__all__ = ['CHECK_MARGIN', 'CHECK_SAMPLES', 'EXACT_CHECKS', 'LOCAL_MARGIN', 'LOCAL_PASSES', 'LOCAL_POWER',
           'PEAK_CHECKS', 'PEAK_SAMPLES', 'S_UNIFORM_CHECKS', 'TOPP_MARGIN']

#: Relative margin kept below the limits (TOPP uses limits * (1 - TOPP_MARGIN)).
TOPP_MARGIN = 1e-3
#: After the dense check every sample satisfies |value| <= limit * (1 - CHECK_MARGIN).
CHECK_MARGIN = 1e-3
#: Samples of the dense check (those nearest a limit) re-verified with exact path derivatives.
EXACT_CHECKS = 32
#: Extra limit-check samples spread uniformly in s (mapped to t).
S_UNIFORM_CHECKS = 250
#: Dense check: ``max(CHECK_SAMPLES, 5 nodes)`` samples uniform in t, then around each of the
#: PEAK_CHECKS highest local peaks of the ratios PEAK_SAMPLES more within one sample spacing
#: (the peaks are seen at a quarter of the spacing, as 4 x CHECK_SAMPLES uniform samples would).
CHECK_SAMPLES = 1000
PEAK_CHECKS = 16
PEAK_SAMPLES = 8
#: Most local slow-down passes of a law, each capping the optimal profile near the samples over a
#: limit, LOCAL_MARGIN below it.
LOCAL_PASSES = 8
LOCAL_MARGIN = 0.01
#: A local pass divides x by the offending sample's speed factor ** LOCAL_POWER (narrow and
#: gentle, repeated, slows the least; see smoothing.LOCAL_WINDOW).
LOCAL_POWER = 1.0

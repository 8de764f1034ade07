"""Confidence of a reported reflection: does a second, independent selection agree with it?

Every reflection the detector reports is a near-isometry that reverses the orientation; that is what
the verification checks (:mod:`.verification`). It does not tell the left-right reflection from a
*competing* near-symmetry: on posed humans, a map that swaps the arms and mirrors each leg onto itself
is as isometric as the wanted one, often more (``BENCHMARKS.md``, "What limits the reflection path").
The geodesic distortion behind ``Symmetry.score`` therefore ranks wrong maps about as high as right
ones. What differs is *stability*: where one reflection stands out, two selections that weigh the
evidence differently pick the same map; where two near-symmetries compete, they tend to pick
different ones.

The second selection is the guided one (``reflection.select_candidate(guided=True)``: each
candidate's upsampling also fits features whose sign a reflection flips), run over the candidates up
to the one chosen, its matrix left at the selection's basis size. The **confidence** is the share of
the vote samples on which its map and the reported dense map land within one KLC radius of each other
(``ReflectionDiagnostics.agreement[0]``), a number in [0, 1]. Where the first selection verified
nothing and the guided selection supplied the map, the other selection is the first one.

Where no second selection ran (``ReflectionConfig.second_opinion=False``) the confidence is the
distortion score ``exp(-distortion^2)``, which does not separate right from wrong maps. Elements
found by the group path carry their score as confidence too: the benchmarks with group ground truth
are too few to calibrate one.

The threshold below which a symmetry is reported as uncertain is ``DetectConfig.min_confidence``; the
rule and the threshold were chosen on SCAPE and TOSCA and are reported on FAUST and TOSCA_Isometric
as well (``scripts/confidence_stats.py``; the numbers are in ``BENCHMARKS.md``).
:func:`confidence_signals` lists the other signals that were measured against the same labels.
"""
from __future__ import annotations

import math

from .result import ReflectionDiagnostics

__all__ = ["confidence_signals", "reflection_confidence"]


def _reported(d: ReflectionDiagnostics):
    """(checks, trials, chosen) of the map reported: the guided selection's where it ran."""
    if d.guided is not None:
        return d.guided, d.guided_trials, d.guided_chosen
    return d.checks, d.trials, d.chosen


def reflection_confidence(d: ReflectionDiagnostics) -> float:
    """Confidence in [0, 1] of the reflection the path reports (see the module doc).

    Args:
        d: the reflection path's diagnostics, with the verification of the reported map.

    Returns:
        The two selections' agreement where a second selection ran, else the distortion score.

    Raises:
        ValueError: ``d`` holds no verified map.
    """
    checks, _, _ = _reported(d)
    if checks is None:
        raise ValueError("the diagnostics hold no verified map (checks is None)")
    if d.agreement is not None:
        return float(min(max(d.agreement[0], 0.0), 1.0))
    return float(checks.score)


def confidence_signals(d: ReflectionDiagnostics) -> dict[str, float]:
    """Every signal measured as a candidate confidence, each oriented so that higher means more
    likely right (``scripts/confidence_stats.py --signals`` prints how well each one separates).

    ``score``, ``neg_distortion``, ``neg_worst``, ``reversal``, ``neg_gap``, ``neg_involution``: the
    verification of the reported map (``Checks``); ``margin`` and ``ratio``: how much more distorted
    the runner-up of the selection was (10 and 100 where no other candidate was measured);
    ``n_compared``: minus the number of other candidates measured; ``sel_distortion`` and
    ``sel_vote``: the chosen candidate's trial; ``cand_ratio``: second over first extrema-permutation
    consistency score (the selection's four: NaN where the functional-map candidate supplied the
    map, which had no trial); ``guided``: -1 where the guided selection supplied the map; ``agree1``,
    ``agree2``: the two selections' agreement within one and two KLC radii; ``same_choice``: 1 where
    both chose the same candidate (NaN where no second selection ran).
    """
    checks, trials, chosen = _reported(d)
    starts = list(d.k0)
    if chosen[0] >= 0:
        trial = trials[chosen[0] * len(starts) + starts.index(chosen[1])]
        best, vote = trial.distortion, trial.vote
    else:  # the functional-map candidate: no trial of the extrema selection
        best, vote = math.nan, math.nan
    others = sorted(t.distortion for j, t in enumerate(trials)
                    if j // len(starts) != chosen[0] and math.isfinite(t.distortion))
    runner = others[0] if others else math.inf
    sc = list(d.candidate_scores)
    second = d.guided_chosen if d.guided is not None else d.second_chosen
    return {
        "score": checks.score,
        "neg_distortion": -checks.distortion,
        "neg_worst": -checks.worst_distortion,
        "reversal": -checks.orientation,
        "neg_gap": -checks.descriptor_gap,
        "neg_involution": -checks.involution_error,
        "margin": min(runner - best, 10.0),
        "ratio": min(runner / max(best, 1e-6), 100.0),
        "n_compared": -float(len(others)),
        "sel_distortion": -best,
        "sel_vote": -vote,
        "cand_ratio": min(sc[1] / max(sc[0], 1e-6), 100.0) if len(sc) > 1 else 100.0,
        "guided": -float(d.guided is not None),
        "agree1": d.agreement[0] if d.agreement is not None else math.nan,
        "agree2": d.agreement[1] if d.agreement is not None else math.nan,
        "same_choice": float(second == d.chosen) if d.guided is None and second is not None else math.nan,
    }

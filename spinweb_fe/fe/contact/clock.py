"""The CPU's cycle counter inside compiled code, for the profile of the crossing audit's and
the cable contact's passes (issue #42: what each nanosecond per pair does).

:func:`cycles` reads the counter LLVM's ``llvm.readcyclecounter`` gives (on x86-64 the time
stamp counter, ``rdtsc``: a constant rate on a CPU with ``constant_tsc``, whatever the core's
clock does; not serializing, so an interval of a few cycles is blurred by the instructions
in flight: the profile times passes, and single pairs only as samples). The counts are in
the counter's ticks; record.profile converts them to seconds with a rate measured against
``time.perf_counter`` over the run. The slots of the two kernels' ``clock`` (ticks) and
``tally`` (counts) arrays are named here; the kernels only ever add to them (no result reads
them), and a run without the audit and the contact compiles none of it.

Audit (fe.contact.touch.AuditKernel ``clock``, ``tally``):

    A_MOTION   the step's motion (fe.contact.bounds.step_motion, when the audit computes
               it) and the largest motion since the build (fe.contact.broad.moved_since)
    A_CERT     the certificates' loop over every listed pair (certified_crossings), whole
    A_LOOK     of it, a sample of the pairs looked at by their relative motion (one in
               :data:`SAMPLE`, tally T_LOOK_SAMPLED): bound_now and pair_motion
    A_EXACT    of it, every pair its relative motion did not rule out: the exact test
               (apart, pair_crossings) if the step is tested, its distance at the end
    A_WIDE     the steps beyond the list's reach: a list of their own and the boxes' test
    T_STEPS, T_READ, T_LOOKED, T_LOOK_SAMPLED, T_CLOSE, T_EXACT, T_PAIR_TEST, T_WIDE,
    T_WIDE_PAIRS: audit steps, pairs read, looked at, sampled, reaching the exact branch,
    tested by ``apart``, by ``pair_crossings``, wide steps, their pairs

Contact (fe.contact.bounds.Certified ``clock``, ``tally``, which the ContactKernel holds):

    C_SELECT   the penalty's near selection over every listed pair (and v_{n-1/2} kept)
    C_CLOSEST  the near pairs' closest points
    C_PUSH     the penalty forces of the pairs in contact
    C_MOTION   the step's motion for the fail-safe (step_motion)
    C_FRICTION the friction's impulses
    C_ROUND0   the fail-safe's first pass over the list (certificates, exact tests, impulses)
    C_ROUNDS   its later rounds (the pairs of the nodes a round moved)
    C_ZONES    its impact zones
    C_REACTION the hub's reaction and the impulses' work
    C_RESOLVE  the fail-safe's first call of a step, whole (the slots above from C_MOTION
               are parts of it)
    C_AGAIN    the calls after a reaction of the hub (fe.phases.settle's k > 0), whole
    N_*        see :data:`CONTACT_TALLY`
"""

from __future__ import annotations

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

#: one looked-at pair in this many is timed (a timed interval costs two counter reads)
SAMPLE = 16

A_MOTION, A_CERT, A_LOOK, A_EXACT, A_WIDE = range(5)
AUDIT_CLOCK = ("motion", "certificates", "looked_at_sample", "exact", "wide")
(T_STEPS, T_READ, T_LOOKED, T_LOOK_SAMPLED, T_CLOSE, T_EXACT, T_PAIR_TEST, T_WIDE,
 T_WIDE_PAIRS) = range(9)
AUDIT_TALLY = ("steps", "pairs_read", "pairs_looked_at", "pairs_looked_at_sampled",
               "pairs_exact_branch", "pairs_apart_tested", "pairs_crossing_tested",
               "wide_steps", "wide_pairs")

(C_SELECT, C_CLOSEST, C_PUSH, C_MOTION, C_FRICTION, C_ROUND0, C_ROUNDS, C_ZONES, C_REACTION,
 C_RESOLVE, C_AGAIN) = range(11)
CONTACT_CLOCK = ("near_selection", "closest_points", "push", "motion", "friction",
                 "failsafe_round0", "failsafe_rounds", "impact_zones", "reaction",
                 "failsafe_first_call", "after_reactions")
(N_PUSH, N_NEAR, N_TOUCH, N_RESOLVE, N_READ0, N_LOOK0, N_EXACT0, N_ROUNDS, N_ROUND_PAIRS,
 N_ZONES, N_AGAIN, N_IMPULSES, N_IMPULSES_AGAIN, N_REACTIONS, N_ROUND_LOOKED) = range(15)
CONTACT_TALLY = ("steps", "near_pairs", "pairs_in_contact", "failsafe_calls",
                 "round0_pairs_read", "round0_pairs_looked_at", "round0_pairs_tested",
                 "later_rounds", "later_round_pairs_tested", "impact_zone_calls",
                 "calls_after_reactions", "impulses", "impulses_after_reactions",
                 "reactions", "later_round_pairs_looked_at")


@intrinsic
def _read_counter(typingctx):
    """The cycle counter (int64 ticks), LLVM's ``llvm.readcyclecounter``."""
    sig = types.int64()

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = builder.module.declare_intrinsic("llvm.readcyclecounter", fnty=fnty)
        return builder.call(fn, [])

    return sig, codegen


@njit(inline="always")
def cycles():
    """The cycle counter now [ticks] (inside compiled code)."""
    return _read_counter()


@njit(inline="always")
def lap(clock, slot, start):
    """Add the ticks since ``start`` to ``clock[slot]``; returns the counter now."""
    now = _read_counter()
    clock[slot] += now - start
    return now


@njit(cache=True)
def counter_now():
    """The cycle counter now [ticks], from Python (for the rate's calibration)."""
    return _read_counter()


@njit(cache=True)
def interval_cost(n):
    """The least ticks an empty timed interval measures (two reads back to back), over
    ``n`` tries: what each timed sample carries besides its work."""
    least = 1 << 62
    for _ in range(n):
        t0 = _read_counter()
        t1 = _read_counter()
        least = min(least, t1 - t0)
    return least

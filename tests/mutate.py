"""Mutation check: do the tests catch small, plausible bugs? (issue #17, docs/testing.md)

Each mutant below is one textual change of one source file (a sign, a factor, a dropped
term). The script copies the project into a temporary folder (without .git, .venv, out/ and
caches), applies one mutant at a time to the copy, runs the listed test files there with
PYTHONPATH pointing at the copy and a private NUMBA_CACHE_DIR, and reports which mutants
the tests kill and how:

- ``assertion``: a test fails on an assertion (what we want);
- ``energy stop`` / ``error``: tests only fail through the run's energy audit or an
  exception (the mutant is caught, but not by a check written for it);
- ``SURVIVED``: every test passed.

The working tree is never modified. Before the mutants, the unmutated copy runs the union
of the test files (it must pass: a test failing there is ignored for the mutants, and the
run warms the numba cache); then the ``canary`` mutant (``damper_tension_negative``, known
to be killed) must be killed, which proves that the copy, not the installed package, is
under test. numba's cache of the fe/ kernels is stamped with the content of the whole
folder (spinweb_fe/fe/cache.py), so a mutant there recompiles them; the report counts the
cache files each fe/ mutant wrote (0 would mean a stale cache, flagged).

Usage (from the project root; CPU heavy, mutants run one at a time)::

    .venv/bin/python tests/mutate.py              # every mutant (hours on 2 cores)
    .venv/bin/python tests/mutate.py --only ID,ID # some of them (the baseline still runs)
    .venv/bin/python tests/mutate.py --list       # the list, nothing run

``make mutate`` runs the first form. The report is printed and written to
``out/mutation/report.json``. Exit code 0 when every mutant of the issue's table and at
least 90 % of the others are killed by an assertion, else 1.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IGNORE = shutil.ignore_patterns(".git", ".venv", "out", "__pycache__", ".pytest_cache",
                                "*.nbi", "*.nbc", "*.egg-info", "build", "*.npz", "img")

KERNEL_TESTS = ("tests/test_kernels.py", "tests/test_hub.py", "tests/test_solver_physics.py",
                "tests/test_mutation_guards.py")
ANALYTIC_TESTS = ("tests/test_analytic.py", "tests/test_analytic_payout.py",
                  "tests/test_mutation_guards.py")
FOLD_TESTS = ("tests/test_fold.py", "tests/test_fold_polygon.py", "tests/test_tethers.py",
              "tests/test_topologies.py")
COIL_TESTS = ("tests/test_coil.py", "tests/test_hub.py", "tests/test_mutation_guards.py")
PAYOUT_TESTS = ("tests/test_payout.py",)
VERDICT_TESTS = ("tests/test_verdict.py",)
SWEEP_TESTS = ("tests/test_montecarlo.py",)
DESIGN_TESTS = ("tests/test_design.py",)
CONTACT_TESTS = ("tests/test_cable_contact.py",)
AUDIT_TESTS = ("tests/test_crossing_audit.py",)
ZONE_TESTS = ("tests/test_impact_zones.py",)
LINK_TESTS = ("tests/test_linking.py", "tests/test_linking_monitor.py")
LAYER_TESTS = ("tests/test_layer_gap.py",)
#: issue #47's guards (fast files; docs/testing.md, "Guards of the round's features")
G_VERDICT = ("tests/test_guards_verdicts.py",)
G_START = ("tests/test_guards_start.py",)
G_DEVICES = ("tests/test_guards_devices.py",)
G_CONTACT = ("tests/test_guards_contact.py",)
G_SWEEP = ("tests/test_guards_sweep.py",)
G_REST = ("tests/test_guards_rest.py",)
G_HUB_WORK = ("tests/test_guards_hub_work.py",)


@dataclass(frozen=True)
class Mutant:
    """One textual change: ``old`` (which must occur exactly once in ``path``) -> ``new``."""

    id: str
    path: str
    old: str
    new: str
    what: str
    tests: tuple = KERNEL_TESTS
    issue: bool = False  # one of the seven bugs of issue #17's table


MUTANTS = (
    # ---- the issue's table (the first is the canary)
    Mutant("damper_tension_negative", "spinweb_fe/fe/law.py",
           "return max(n_el + taut * cdamp_e * ldot, 0.0)",
           "return n_el + taut * cdamp_e * ldot",
           "damped cables: total tension allowed to go negative", issue=True),
    Mutant("friction_bound_doubled", "spinweb_fe/fe/hub/contact.py",
           "p_max = mu * m * dvn", "p_max = 2.0 * mu * m * dvn",
           "Coulomb friction: impulse bound mu x normal impulse doubled", issue=True),
    Mutant("torque_work_old_rate", "spinweb_fe/fe/step.py",
           "incr[term.torque_work] = kick.torque * dt * 0.5 * (kick.rate_old + kick.rate_new)",
           "incr[term.torque_work] = kick.torque * dt * kick.rate_old",
           "hub torque work with the old hub rate instead of the half-step mean", issue=True),
    Mutant("root_tension_accel_doubled", "spinweb_fe/analytic/models.py",
           "return m_f * p.r0 * (omega * omega * c - omega_dot * s) + S * psi * psi",
           "return m_f * p.r0 * (omega * omega * c - 2.0 * omega_dot * s) + S * psi * psi",
           "analytical root tension: the hub-acceleration term doubled", ANALYTIC_TESTS,
           issue=True),
    Mutant("printed_coiled_initial_inertia", "spinweb_fe/analytic/models.py",
           "return (p.J_hub + n * r0 * r0 * m_f, 0.0, n * sigma * r0 * S * psi * psi,",
           "return (p.J0, 0.0, n * sigma * r0 * S * psi * psi,",
           "printed model, coiled: J_hub + n r0^2 m_f replaced by the initial inertia",
           ANALYTIC_TESTS, issue=True),
    Mutant("contact_force_correction_dropped", "spinweb_fe/fe/hub/contact.py",
           "    diss += 0.5 * dt * (force[i, 0] * (vel[i, 0] - vx0) + force[i, 1] * "
           "(vel[i, 1] - vy0))\n", "",
           "contact dissipation without the step-force correction term", issue=True),
    Mutant("ramp_tied_torque_sign", "spinweb_fe/fe/hub/axis.py",
           "return j_eff * (w_new - w_old) / dt - tau, w_new",
           "return j_eff * (w_new - w_old) / dt + tau, w_new",
           "spin-ramp torque: sign of the tied-node torque flipped", issue=True),
    # ---- element law (fe/law.py), force passes (fe/forces.py) and step (fe/step.py)
    Mutant("compression_carried", "spinweb_fe/fe/law.py",
           "return inv, max(ln * inv_rest_e - 1.0, 0.0)", "return inv, ln * inv_rest_e - 1.0",
           "cables carry compression (tension-only removed)"),
    Mutant("strain_energy_doubled", "spinweb_fe/fe/forces.py",
           "buf[6, k] = 0.5 * n_el * strain / inv_rest[e]",
           "buf[6, k] = n_el * strain / inv_rest[e]",
           "strain energy EA eps^2 L0 instead of EA eps^2 L0 / 2"),
    Mutant("damper_while_slack", "spinweb_fe/fe/law.py",
           "taut = 1.0 if strain > 0.0 else 0.0", "taut = 1.0",
           "the damper acts on slack elements too"),
    Mutant("damping_power_total", "spinweb_fe/fe/forces.py",
           "buf[3, k] = (n_tot - n_el) * ldot", "buf[3, k] = n_tot * ldot",
           "damping power counts the elastic force too"),
    Mutant("second_end_sign", "spinweb_fe/fe/forces.py",
           "                sx -= fx[e]\n", "                sx += fx[e]\n",
           "node sums: the element force on its second end with the wrong sign (x only)"),
    Mutant("extra_elements_dropped", "spinweb_fe/fe/forces.py",
           "force[i, d] += sign * ef[d, e]", "force[i, d] += 0.0 * ef[d, e]",
           "node sums: the elements of a node beyond its table's slots left out",
           ("tests/test_strength.py",)),
    Mutant("threads_in_element_order", "spinweb_fe/fe/forces.py",
           'return np.argsort(key, kind="stable").astype(np.int64)',
           "return np.arange(len(key), dtype=np.int64)",
           "threads take the element blocks in element order (each thread's ends across all "
           "nodes: the positions' cache lines travel between the cores every step)",
           ("tests/test_threads.py",)),
    Mutant("thread_block_order_halved", "spinweb_fe/fe/forces.py",
           "            b = order[q]\n", "            b = order[q // 2]\n",
           "threads: element blocks in work.order taken twice, half of them never",
           ("tests/test_threads.py", "tests/test_strength.py", "tests/test_guards_rest.py")),
    Mutant("helper_phase_types_drift", "spinweb_fe/run/warmup.py",
           "state.strength.broken, types.Omitted(None))),",
           "state.strength.broken, None)),",
           "compile helper: a phase listed with other types than the loop passes (its work "
           "lost, the phase compiled twice)", ("tests/test_warmup.py",)),
    Mutant("field_forces_never_passed", "spinweb_fe/record/parts.py",
           "    def kernel(self, hooks: dict):\n        return self.tidal",
           "    def kernel(self, hooks: dict):\n        return None",
           "the step loop never gets the gravity gradient's node forces on a fixed axis (numba "
           "prunes the field: no tidal loads)", ("tests/test_free_hub.py",)),
    Mutant("render_probe_left_running", "spinweb_fe/post/render.py",
           "_pending.pop().stop()",
           "_pending.pop()",
           "a test render no one asked is left running when a picture fails",
           ("tests/test_render.py",)),
    Mutant("kinetic_energy_new_half_step", "spinweb_fe/fe/hub/axis.py",
           "ke = 0.5 * (sums[0] + sums[1]) + 0.25 * j_eff * (w_old * w_old + w_new * w_new)",
           "ke = sums[1] + 0.5 * j_eff * w_new * w_new",
           "kinetic energy recorded from v_{n+1/2} only"),
    Mutant("momentum_new_half_step", "spinweb_fe/fe/hub/axis.py",
           "lz = 0.5 * (sums[2] + sums[3]) + j_eff * 0.5 * (w_old + w_new)",
           "lz = sums[3] + j_eff * w_new",
           "angular momentum recorded from v_{n+1/2} only"),
    Mutant("start_half_step_sign", "spinweb_fe/fe/hub/axis.py",
           "vel -= 0.5 * dt * force * state.node_inv_mass[:, None]",
           "vel += 0.5 * dt * force * state.node_inv_mass[:, None]",
           "start v_{-1/2} = v_0 + dt/2 a_0 (first order)"),
    Mutant("probe_velocity_not_averaged", "spinweb_fe/fe/step.py",
           "rec.probe_vel[k, p, d] = 0.5 * (vprobe[p, d] + vel[probes[p], d])",
           "rec.probe_vel[k, p, d] = vel[probes[p], d]",
           "probe (tip) velocity recorded as v_{n+1/2}, not the mean",
           KERNEL_TESTS + ("tests/test_arms.py",)),
    Mutant("hub_angle_old_rate", "spinweb_fe/fe/phases.py",
           "theta = theta + dt * kick.rate_new",
           "theta = theta + dt * kick.rate_old",
           "hub angle advanced with omega_{n-1/2}"),
    Mutant("damping_dissipation_halved", "spinweb_fe/fe/step.py",
           "incr[term.damping_dissipation] = pdamp * dt",
           "incr[term.damping_dissipation] = 0.5 * pdamp * dt",
           "damping dissipation accumulated at half its value"),
    Mutant("contact_dissipation_dropped", "spinweb_fe/fe/step.py",
           "incr[term.contact_dissipation] = dcontact",
           "incr[term.contact_dissipation] = 0.0",
           "contact dissipation not accumulated"),
    # ---- hub on a fixed axis (fe/hub/axis.py)
    Mutant("hub_reaction_sign", "spinweb_fe/fe/hub/axis.py",
           "return value, w_old + dt * (value + tau) / j_eff",
           "return value, w_old + dt * (value - tau) / j_eff",
           "the tied nodes' reaction turns the hub the wrong way"),
    Mutant("moment_sign", "spinweb_fe/fe/hub/axis.py",
           "tau += pos[i, 0] * force[i, 1] - pos[i, 1] * force[i, 0]",
           "tau += pos[i, 0] * force[i, 1] + pos[i, 1] * force[i, 0]",
           "z-moment x f_y + y f_x"),
    Mutant("ramp_rate_at_step", "spinweb_fe/fe/hub/axis.py",
           "_, w_new = eval_control(law, t + 0.5 * dt, w_old)",
           "_, w_new = eval_control(law, t, w_old)",
           "prescribed rate imposed at t_n instead of the half step"),
    Mutant("tied_velocity_sign", "spinweb_fe/fe/hub/rigid.py",
           "vel[i, 0] = -omega * y", "vel[i, 0] = omega * y",
           "tied and held nodes' velocity not omega e_z x x"),
    # ---- control laws (fe/control.py)
    Mutant("feedback_sign", "spinweb_fe/fe/control.py",
           "return False, p[0] * (1.0 - omega / p[1])",
           "return False, p[0] * (1.0 + omega / p[1])",
           "torque feedback M0 (1 + omega/omega0)"),
    Mutant("ramp_never_ends", "spinweb_fe/fe/control.py",
           "        return True, p[0]\n    if law.code == 3",
           "        return True, p[0] * t / p[1]\n    if law.code == 3",
           "spin ramp keeps accelerating after ramp_time"),
    Mutant("analytic_ramp_no_acceleration", "spinweb_fe/fe/control.py",
           "return p[0] * t / p[1], p[0] / p[1]", "return p[0] * t / p[1], 0.0",
           "the ramp's analytical form loses its acceleration", ANALYTIC_TESTS),
    # ---- contact (fe/hub/contact.py)
    Mutant("contact_pushes_out", "spinweb_fe/fe/hub/contact.py",
           "dvn = min(s / dt, max(-(vx0 * ex + vy0 * ey), 0.0))", "dvn = s / dt",
           "contact impulse may push a node outwards"),
    Mutant("friction_reaction_sign", "spinweb_fe/fe/hub/contact.py",
           "omega -= p * rn / j_eff", "omega += p * rn / j_eff",
           "friction moment on the hub with the wrong sign"),
    Mutant("stick_ignores_hub", "spinweb_fe/fe/hub/contact.py",
           "p_stick = -vrel / (1.0 / m + rn * rn / j_eff)", "p_stick = -vrel * m",
           "stick impulse ignores the hub's own response"),
    Mutant("landing_root_sign", "spinweb_fe/fe/hub/contact.py",
           "return -pr + np.sqrt(max(disc, 0.0))", "return -pr - np.sqrt(max(disc, 0.0))",
           "the other root of the landing equation (no contact impulse)"),
    # ---- held coil (fe/coil/levels.py)
    Mutant("held_moment_sign", "spinweb_fe/fe/coil/levels.py",
           "tau += pos[i, 0] * force[i, 1] - pos[i, 1] * force[i, 0]",
           "tau += pos[i, 0] * force[i, 1] + pos[i, 1] * force[i, 0]",
           "moment of the forces on the held coil with the wrong sign", COIL_TESTS),
    Mutant("release_keeps_inertia", "spinweb_fe/fe/coil/levels.py",
           "inertia -= nodes.mass[i] * (coil.level_ref[p, 0] ** 2 + coil.level_ref[p, 1] ** 2)",
           "inertia -= 0.0 * nodes.mass[i]",
           "a released level stays in the hub's inertia", COIL_TESTS),
    # ---- analytical model (analytic/models.py, analytic/integrate.py, analytic/regimes.py)
    Mutant("consistent_coiled_arm_row", "spinweb_fe/analytic/models.py",
           "-2.0 * sigma * r0 * S * psi * (omega - 0.5 * psi))",
           "-2.0 * sigma * r0 * S * psi * (omega - psi))",
           "consistent coiled arm row: Psi/2 -> Psi", ANALYTIC_TESTS),
    Mutant("second_moment", "spinweb_fe/analytic/models.py",
           "I = lin * L2 * L2 / 6.0", "I = lin * L2 * L2 / 4.0",
           "second moment of the Eq. 7 arm L^4/4 instead of L^4/6", ANALYTIC_TESTS),
    Mutant("tip_rate_denominator", "spinweb_fe/analytic/models.py",
           "return h / (r0 * r0 + L * L + 2.0 * r0 * L * c)",
           "return h / (r0 * r0 + L * L + r0 * L * c)",
           "tip rate: |r|^2 without the factor 2 of the cross term", ANALYTIC_TESTS),
    Mutant("momentum_cross_term", "spinweb_fe/analytic/models.py",
           "K = p.J0 * omega + n * (I * psi + r0 * S * c * (omega + psi))",
           "K = p.J0 * omega + n * (I * psi + r0 * S * c * psi)",
           "angular momentum invariant: cross term without omega", ANALYTIC_TESTS),
    Mutant("printed_pivot_arm_row", "spinweb_fe/analytic/models.py",
           "m_f * r0 * c, S, -m_f * r0 * s * omega * omega)",
           "m_f * r0 * c, I, -m_f * r0 * s * omega * omega)",
           "printed pivoting arm row with I instead of S", ANALYTIC_TESTS),
    Mutant("work_with_arm_rate", "spinweb_fe/analytic/integrate.py",
           "return [y[2], y[3] - y[2], wd, pd, M * y[2], M, reg.rate(ctx, t, y), Ldd][:size]",
           "return [y[2], y[3] - y[2], wd, pd, M * y[3], M, reg.rate(ctx, t, y), Ldd][:size]",
           "analytical torque work integrates M Psi", ANALYTIC_TESTS),
    Mutant("captured_inertia_hub_only", "spinweb_fe/analytic/regimes.py",
           'base = p.J0 if model == "consistent" else',
           'base = p.J_hub if model == "consistent" else',
           "consistent captured inertia without the coil", ANALYTIC_TESTS),
    # ---- fold and coil geometry (meshgen/fold.py)
    Mutant("coil_direction", "meshgen/fold.py",
           "ang = np.where(spoke, psi, psi - w * (qk - l0) / r0)",
           "ang = np.where(spoke, psi, psi + w * (qk - l0) / r0)",
           "coil wound the other way", FOLD_TESTS),
    Mutant("spoke_radius", "meshgen/fold.py",
           "r = np.where(spoke, r0 + (l0 - qk), r0)",
           "r = np.where(spoke, r0 + 0.5 * (l0 - qk), r0)",
           "coil lead-in squeezed to half its length", FOLD_TESTS),
    Mutant("star_run_out", "meshgen/fold.py",
           "r = r_c + l[out] - l_c", "r = r_c + 0.5 * (l[out] - l_c)",
           "star-folded arms at half their length", FOLD_TESTS),
    Mutant("no_lead_in", "meshgen/fold.py",
           "return 0.0 if c is None else mesh.arm_root_coord - corner_coord(c, mesh.n_arms)",
           "return 0.0", "frame web coiled without its lead-in", FOLD_TESTS),
    # ---- energy audit (record/energy.py)
    Mutant("warn_every_chunk", "spinweb_fe/record/energy.py",
           "if err > ENERGY_WARN and not self.warned:", "if err > ENERGY_WARN:",
           "the energy warning repeats", ("tests/test_mutation_guards.py",)),
    Mutant("balance_contact_sign", "spinweb_fe/fe/layout.py",
           'Term("contact_dissipation", 1, "J",', 'Term("contact_dissipation", -1, "J",',
           "energy balance subtracts the contact dissipation (its sign in fe.layout.ENERGY)",
           ("tests/test_hub.py", "tests/test_mutation_guards.py")),
    # ---- payout devices (fe/coil/payout.py, fe/coil/brake.py, fe/coil/line.py, the axis's device phase) and their
    #      analytical twins (issue #24)
    Mutant("reel_ahead_of_law", "spinweb_fe/fe/coil/brake.py",
           "return min(cs.s_dev[k], coil.arm_end[k] - law_value(coil.law_t, coil.law_v, t))",
           "return min(cs.s_dev[k], coil.arm_end[k] - 1.01 * law_value(coil.law_t, coil.law_v, "
           "t))", "the reel lets out 1 % more than its law", PAYOUT_TESTS),
    Mutant("passing_mass_without_line_speed", "spinweb_fe/fe/coil/payout.py",
           "c = u / size if size > 0.0 else 0.0", "c = 0.0",
           "mass passing D joins the line with D's velocity, not the line's", PAYOUT_TESTS),
    Mutant("device_pairing_dropped", "spinweb_fe/fe/coil/devices.py",
           "e0 += 0.5 * line_pairing(coil, cs, k, elems, mv, pose, lev, dt, steps)",
           "e0 += 0.0 * line_pairing(coil, cs, k, elems, mv, pose, lev, dt, steps)",
           "the device's work without the leapfrog pairing before its update", PAYOUT_TESTS),
    Mutant("device_moment_sign", "spinweb_fe/fe/phases.py",
           "tau += cs.dev_moment[2]", "tau -= cs.dev_moment[2]",
           "the device's moment on the fixed axis with the wrong sign", PAYOUT_TESTS),
    Mutant("brake_slips_twice_as_far", "spinweb_fe/fe/coil/brake.py",
           "        x = _dissipative(coil, cs, k, lev, elems, mv, pose, force, x, dt)",
           "        x = 2.0 * _dissipative(coil, cs, k, lev, elems, mv, pose, force, x, dt)",
           "the brake's return mapping slips twice as far as the force allows", PAYOUT_TESTS),
    Mutant("brake_dissipation_unlimited", "spinweb_fe/fe/coil/brake.py",
           "        x = _dissipative(coil, cs, k, lev, elems, mv, pose, force, x, dt)",
           "        x = x",
           "the brake's slip not limited by its dissipation (a web's brake supplies energy)",
           PAYOUT_TESTS),
    Mutant("analytic_brake_force_sign", "spinweb_fe/analytic/payout.py",
           "b = np.array([-r1, -(r0 * S * u * u * sb + 2.0 * S * Ld * psi), c - force * opw])",
           "b = np.array([-r1, -(r0 * S * u * u * sb + 2.0 * S * Ld * psi), c + force * opw])",
           "analytical brake: the slip equation with the force's sign flipped", PAYOUT_TESTS),
    # ---- the survivors of issue #28's round, now guarded
    Mutant("eq7_density_at_first_end", "spinweb_fe/case/scene.py",
           "s = mesh.node_arm_coord[mesh.elem_nodes].mean(axis=1)",
           "s = mesh.node_arm_coord[mesh.elem_nodes].min(axis=1)",
           "Eq. 7 tether masses from the density at each element's first end",
           ("tests/test_tethers.py",)),
    Mutant("cfl_zero_accepted", "spinweb_fe/case/load.py",
           'elif chk == "frac" and not 0 < value <= 1:',
           'elif chk == "frac" and not 0 <= value <= 1:',
           "time.cfl = 0 (and other fractions of zero) accepted", ("tests/test_bad_input.py",)),
    Mutant("release_stretch_unsquared", "spinweb_fe/fe/coil/levels.py",
           "taut = (dx * dx + dy * dy + dz * dz) * elems.inv_rest[e] ** 2 > 1.0",
           "taut = (dx * dx + dy * dy + dz * dz) * elems.inv_rest[e] > 1.0",
           "the release's taut test without the square of 1/L0 (hidden by 1 m elements)",
           ("tests/test_coil.py",)),
    Mutant("free_start_full_torque_step", "spinweb_fe/fe/hub/body.py",
           "rs.momentum[:] = rs.momentum - 0.5 * dt * value * b3",
           "rs.momentum[:] = rs.momentum - dt * value * b3",
           "free hub's start: a whole step of the control torque's impulse, not a half",
           ("tests/test_free_hub.py",)),
    Mutant("bundle_spine_own_inverse_mass", "spinweb_fe/fe/coil/levels.py",
           "inv_mass[i] = 1.0 / level_mass[lev] if first else 0.0",
           "inv_mass[i] = node_inv_mass[i] if first else 0.0",
           "a bundled level's spine node kicked with its own inverse mass, not the level's",
           ("tests/test_coil.py", "tests/test_guards_rest.py")),
    Mutant("contact_centre_translates_only", "spinweb_fe/fe/hub/body.py",
           "hull[2] = c + dt * (rs.velocity + cross(w, c - rs.position))",
           "hull[2] = c + dt * rs.velocity",
           "the free hub's predicted centre for contact ignores its turn about the centre of "
           "mass", ("tests/test_free_hub.py",)),
    # ---- verdicts and Monte-Carlo sweeps (issue #25)
    Mutant("verdict_recoil_running_min", "spinweb_fe/record/verdict.py",
           "back = np.maximum.accumulate(radius, axis=0) - radius",
           "back = np.minimum.accumulate(radius, axis=0) - radius",
           "re-coil measured from the tip's nearest, not its farthest", VERDICT_TESTS),
    Mutant("verdict_deployed_first_out", "spinweb_fe/record/verdict.py",
           "return short, len(short) - int(np.argmax(short[::-1])) if short.any() else 0",
           "return short, int(np.argmax(~short)) if (~short).any() else len(short)",
           "deployed from the first time the tips are out, not for good", VERDICT_TESTS),
    Mutant("verdict_swing_full_range", "spinweb_fe/record/verdict.py",
           "amp = 0.5 * (after.max(axis=0) - after.min(axis=0))",
           "amp = after.max(axis=0) - after.min(axis=0)",
           "swing as the whole range of phi, not half of it", VERDICT_TESTS),
    Mutant("verdict_prescribed_by_trapezoid", "spinweb_fe/record/verdict.py",
           "by_work = np.abs(wm) > 1e-6", "by_work = np.abs(wm) < 1e-6",
           "a prescribed rate's impulse from the sampled torque's trapezoid", VERDICT_TESTS),
    Mutant("verdict_na_fails", "spinweb_fe/record/verdict.py",
           "return all(c.passed is not False for c in criteria if c.required)",
           "return all(c.passed is True for c in criteria if c.required)",
           "a criterion that does not apply fails the verdict", VERDICT_TESTS),
    Mutant("verdict_slack_counts_taut", "spinweb_fe/record/verdict.py",
           "slack = np.sqrt(np.einsum(\"ij,ij->i\", d, d)) <= rest_len",
           "slack = np.sqrt(np.einsum(\"ij,ij->i\", d, d)) >= rest_len",
           "the slack share counts the taut elements", VERDICT_TESTS),
    Mutant("montecarlo_one_generator", "spinweb_fe/sweep/draws.py",
           "rng = np.random.default_rng((seed, member))", "rng = np.random.default_rng(seed)",
           "every member draws from the same generator (all members alike)", SWEEP_TESTS),
    Mutant("wilson_is_exact", "spinweb_fe/sweep/draws.py",
           'proportion_ci(confidence, method="wilson")',
           'proportion_ci(confidence, method="exact")',
           "the pass rate's interval is Clopper-Pearson's, not Wilson's", SWEEP_TESTS),
    Mutant("montecarlo_best_is_worst", "spinweb_fe/sweep/report.py",
           "worst = max(positions, key=badness) if n else None",
           "worst = min(positions, key=badness) if n else None",
           "the sweep names its best member as the worst", SWEEP_TESTS),
    Mutant("design_bisect_keeps_the_failure", "spinweb_fe/sweep/design.py",
           "                s[0], s[2] = 0.5 * (s[0] + s[1]), mid",
           "                s[1] = 0.5 * (s[0] + s[1])",
           "the design's bisection moves its failing end where the midpoint passes",
           DESIGN_TESTS),
    Mutant("design_bound_margin_sign", "spinweb_fe/sweep/design.py",
           "margins.append(1.0 - v / lim if math.isfinite(v) else -1.0)",
           "margins.append(v / lim - 1.0 if math.isfinite(v) else -1.0)",
           "a bound's margin with the wrong sign (a point far inside it seen as failing)",
           DESIGN_TESTS),
    Mutant("design_bound_ignored", "spinweb_fe/sweep/design.py",
           "        if not v <= lim:\n            failed.append(b)",
           "        if not v <= 10.0 * lim:\n            failed.append(b)",
           "the design's bounds checked ten times too loosely", DESIGN_TESTS),
    # ---- crossings, contact, linking, stacked layers (issue #26)
    Mutant("contact_force_half_on_first", "spinweb_fe/fe/contact/penalty.py",
           "            force[b, j] += s * fj",
           "            force[b, j] += 0.5 * s * fj",
           "the contact's force on the first element's second node halved", CONTACT_TESTS),
    Mutant("contact_failsafe_wrong_side", "spinweb_fe/fe/contact/failsafe.py",
           "side = 1.0 if dist0 >= 0.0 else -1.0",
           "side = -1.0 if dist0 >= 0.0 else 1.0",
           "the fail-safe pushes a pair out on the side it was going to", CONTACT_TESTS),
    Mutant("fixed_hub_no_contact_reaction", "spinweb_fe/fe/contact/failsafe.py",
           "            rate[0] += dw", "            rate[0] += 0.0 * dw",
           "a fixed hub does not take the reaction of the contact's impulses", CONTACT_TESTS),
    Mutant("contact_no_impact_zones", "spinweb_fe/fe/contact/failsafe.py",
           "    if left > 0:  # the rounds ran out: the pairs still crossing move as rigid zones",
           "    if left < 0:  # the rounds ran out: the pairs still crossing move as rigid zones",
           "the crossings the pair impulses' rounds leave are not gathered into zones",
           ZONE_TESTS),
    Mutant("later_passes_miss_pairs", "spinweb_fe/fe/contact/zones.py",
           "            if stamp[p] != tick:", "            if stamp[p] == tick:",
           "the passes after the first test none of the moved nodes' pairs", ZONE_TESTS),
    Mutant("impact_zone_no_spin", "spinweb_fe/fe/contact/zones.py",
           "                w[d] += c * axes[d, k]", "                w[d] += 0.0 * c * axes[d, k]",
           "an impact zone moves without turning: its angular momentum is lost", ZONE_TESTS),
    Mutant("impact_zone_not_with_hub", "spinweb_fe/fe/contact/zones.py",
           "                hub_zone(group, pos1, vel, inv_mass, dt, hub, follow)",
           "                pass",
           "a zone with a node of the hub does not move with the hub", ZONE_TESTS),
    Mutant("stuck_nodes_left_behind_free_hub", "spinweb_fe/fe/contact/impulses.py",
           "    stuck = follow is not None and np.any(follow)", "    stuck = False",
           "the nodes an impact zone stuck to a free hub do not take its reaction with it",
           ZONE_TESTS),
    Mutant("stuck_nodes_left_behind_axis", "spinweb_fe/fe/contact/impulses.py",
           "    if not np.any(follow):", "    if True:",
           "the nodes an impact zone stuck to a fixed axis do not turn with it", ZONE_TESTS),
    Mutant("last_pass_moves_the_body", "spinweb_fe/fe/contact/impulses.py",
           "        if place:\n            X[d] += dt * dV[d]",
           "        if True:\n            X[d] += dt * dV[d]",
           "the free hub's reaction in the step's last pass moves it after the pass's test",
           ZONE_TESTS),
    Mutant("free_hub_no_contact_reaction", "spinweb_fe/fe/contact/failsafe.py",
           "work_hub = body_reaction(body, pos, ck.vel1, vel, inv_mass, h0.velocity,\n"
           "                                     h0.omega, dt, ck.follow, place)",
           "work_hub = 0.0",
           "a free hub does not take the reaction of the contact's impulses", CONTACT_TESTS),
    Mutant("audit_released_only", "spinweb_fe/record/crossings.py",
           "        active = np.where(rigid, RIGID, 1).astype(np.int8)",
           "        active = (~rigid).astype(np.int8)",
           "the audit lists released material only: cables pass through the coil unseen",
           AUDIT_TESTS),
    Mutant("broad_phase_skips_rigid_grid", "spinweb_fe/fe/contact/broad.py",
           "        if active[e] != RIGID:",
           "        if active[e] == RIGID:",
           "the broad phase pairs no free element with the held coil's",
           ("tests/test_crossing.py", *AUDIT_TESTS)),
    Mutant("broad_phase_pair_cell_of_the_smaller_corner", "spinweb_fe/fe/contact/broad.py",
           "if (max(span[e, 0], span[f, 0]) != i", "if (min(span[e, 0], span[f, 0]) != i",
           "the broad phase takes a pair in a cell that one of its boxes may not touch: "
           "pairs across a cell face lost", ("tests/test_crossing.py",)),
    Mutant("broad_phase_touching_boxes_apart", "spinweb_fe/fe/contact/broad.py",
           "if (lo[e, 0] > hi[f, 0] or lo[f, 0] > hi[e, 0]",
           "if (lo[e, 0] >= hi[f, 0] or lo[f, 0] > hi[e, 0]",
           "the broad phase drops boxes that touch (a pair a skin apart exactly)",
           ("tests/test_crossing.py",)),
    Mutant("penalty_skips_held", "spinweb_fe/fe/contact/penalty.py",
           "        if max(inv_mass[a], inv_mass[b]) + max(inv_mass[c], inv_mass[d]) == 0.0:",
           "        if min(inv_mass[a], inv_mass[b], inv_mass[c], inv_mass[d]) == 0.0:",
           "the penalty leaves out every pair with a held or tied node", CONTACT_TESTS),
    Mutant("again_pass_tests_nothing", "spinweb_fe/fe/contact/failsafe.py",
           "                                       (inv_mass == 0.0) | ck.follow, ck.follow, "
           "threads)",
           "                                       (inv_mass < 0.0) & ck.follow, ck.follow, "
           "threads)",
           "the pass after the hub placed its nodes again tests none of their pairs",
           CONTACT_TESTS),
    Mutant("audit_world_frame_skin", "spinweb_fe/fe/contact/touch.py",
           "moved = moved_since(au.ref, pos, math.cos(theta), math.sin(theta))",
           "moved = moved_since(au.ref, pos, 1.0, 0.0)",
           "the audit's skin measured in the world frame: the spin forces rebuilds",
           AUDIT_TESTS),
    Mutant("audit_touching_counted", "spinweb_fe/fe/contact/broad.py",
           "or (entering and dist[p] <= touch)",
           "or (entering and dist[p] < 0.0)",
           "pairs that enter the list touching (stacked layers) are tested as any other",
           AUDIT_TESTS),
    Mutant("linking_sign_flipped", "spinweb_fe/record/linking.py",
           "return 2.0 * math.atan2(x1 * y2 + x2 * y1, x1 * x2 - y1 * y2)",
           "return -2.0 * math.atan2(x1 * y2 + x2 * y1, x1 * x2 - y1 * y2)",
           "linking numbers with the wrong sign", LINK_TESTS),
    Mutant("layer_gap_half_spacing", "meshgen/layers.py",
           "KAPPA = 1.1", "KAPPA = 0.5",
           "the coil's passes rise half of what keeps them apart", LAYER_TESTS),
    # ---- issue #47: the round's features, each with a guard of tests/test_guards_*.py
    Mutant("recoil_reports_worst_arm", "spinweb_fe/record/verdict.py",
           "    k = int(np.argmax(share[i]))\n",
           "    k = int(np.argmax(share.max(axis=0)))\n",
           "re-coil: the arm that fell back farthest reported, not the first to fail", G_VERDICT),
    Mutant("swing_time_from_run_start", "spinweb_fe/record/verdict.py",
           "j, when = _first(np.any(out, axis=1), t[i0:])",
           "j, when = _first(np.any(out, axis=1), t)",
           "the swing's first failure timed from the run's start, not its window", G_VERDICT),
    Mutant("swing_reports_worst_arm", "spinweb_fe/record/verdict.py",
           "arm=int(np.argmax(np.abs(after[j] - mid))), detail=window)",
           "arm=int(np.argmax(amp)), detail=window)",
           "swing: the arm of the largest swing reported, not the first out", G_VERDICT),
    Mutant("overstrain_arm_at_peak", "spinweb_fe/record/verdict.py",
           "arm_of = int(np.asarray(h[\"max_strain_arm\"])[i])",
           "arm_of = int(np.asarray(h[\"max_strain_arm\"])[int(np.argmax(u))])",
           "overstrain: the arm of the peak utilisation, not of the first row above 1",
           G_VERDICT),
    Mutant("severity_deployed_share_inverted", "spinweb_fe/record/verdict.py",
           "r = c.limit / max(c.value, 1e-300) if math.isfinite(c.value) else math.inf",
           "r = c.value / c.limit if math.isfinite(c.value) else math.inf",
           "severity: the deployed share as value / limit (a good deployment ranked worst)",
           G_VERDICT),
    Mutant("failed_run_not_worst", "spinweb_fe/sweep/report.py",
           "return math.inf if rows[i][\"status\"] != \"ok\" or sev != sev else sev",
           "return 0.0 if rows[i][\"status\"] != \"ok\" or sev != sev else sev",
           "a Monte-Carlo member that failed to run ranked best, not worst", G_VERDICT),
    Mutant("free_hub_impulse_x_axis", "spinweb_fe/record/verdict.py",
           "axis_z = np.asarray(h[\"hub_axis\"])[:, 2]",
           "axis_z = np.asarray(h[\"hub_axis\"])[:, 0]",
           "a free hub's torque impulse projected on the axis's x part", G_VERDICT),
    Mutant("steady_solved_at_omega", "spinweb_fe/case/scene.py",
           "st = solve_steady(structure_from_model(model), 2.0 * math.sin(0.5 * phi) / dt)",
           "st = solve_steady(structure_from_model(model), omega)",
           "the steady start solved at the continuous omega, not the scheme's discrete rate",
           G_START),
    Mutant("steady_velocity_at_omega", "spinweb_fe/case/scene.py",
           "    rate = math.sin(phi) / dt\n", "    rate = omega\n",
           "the steady start's velocities at omega, not sin(omega dt) / dt", G_START),
    Mutant("axis_first_half_step_whole", "spinweb_fe/fe/hub/axis.py",
           "rate[0] -= 0.5 * dt * (value + tau) / state.hub.inertia[0]",
           "rate[0] -= dt * (value + tau) / state.hub.inertia[0]",
           "the fixed axis's first half step takes a whole step of its loads", G_START),
    Mutant("helper_compiles_nothing", "spinweb_fe/run/warmup.py",
           "            fn.compile(sig)\n", "            pass\n",
           "the compile helper forks and compiles nothing", G_START),
    Mutant("later_rounds_read_the_stale_motion", "spinweb_fe/fe/contact/failsafe.py",
           "                        cert.level, cert.motion, p, e, g) - moved_pair_motion(\n"
           "                        cert.motion, pos0, pos1, a, b, c, d, frame) > sep:",
           "                        cert.level, cert.motion, p, e, g) - pair_motion(\n"
           "                        cert.motion, a, b, c, d) > sep:",
           "the fail-safe's later passes read the certificates against the motion before the "
           "impulses moved the nodes (pairs pushed into each other ruled out)", ZONE_TESTS),
    Mutant("settle_compiles_the_dead_hub", "spinweb_fe/fe/phases.py",
           "        if body is not None:\n            n, left = contact_resolve(",
           "        else:\n            n, left = contact_resolve(",
           "the contact's settle on a fixed axis compiles the free hub's passes too (an else "
           "of 'axis is not None': 14 s more of every cold contact compile)",
           ("tests/test_architecture.py",)),
    Mutant("helper_never_stopped", "spinweb_fe/run/warmup.py",
           "                os.kill(pid, signal.SIGTERM)\n", "                pass\n",
           "the compile helper is left compiling after the loop is compiled", G_START),
    Mutant("fe_law_from_first_point", "spinweb_fe/fe/coil/levels.py",
           "return vv[q - 1] + (vv[q] - vv[q - 1]) * (t - tt[q - 1]) / (tt[q] - tt[q - 1])",
           "return vv[q - 1] + (vv[q] - vv[q - 1]) * (t - tt[0]) / (tt[q] - tt[0])",
           "a payout or brake table interpolated over the wrong interval (FE)", G_DEVICES),
    Mutant("analytic_payout_slope_before", "spinweb_fe/analytic/payout.py",
           "q = int(np.searchsorted(ts, t, side=\"right\")) - 1",
           "q = int(np.searchsorted(ts, t, side=\"left\")) - 1",
           "analytical payout: at a table point the slope of the segment before it",
           G_DEVICES),
    Mutant("device_damping_no_clamp", "spinweb_fe/fe/coil/payout.py",
           "n_tot = max(n_el + (cdamp[e] * ldot if strain > 0.0 else 0.0), 0.0)",
           "n_tot = n_el + (cdamp[e] * ldot if strain > 0.0 else 0.0)",
           "the device's damping correction without the tension-only clamp", G_DEVICES),
    Mutant("brake_cap_speed_plus_length", "spinweb_fe/fe/coil/brake.py",
           "cap = min(level, stretch + SLIP_SPEED * v_max * dt)",
           "cap = min(level, stretch + SLIP_SPEED * v_max)",
           "the brake's slip bound adds a speed to a length", G_DEVICES),
    Mutant("crossing_closed_at_both_ends", "spinweb_fe/fe/contact/crossing.py",
           "return 0.0 <= s < 1.0 and 0.0 <= u < 1.0",
           "return 0.0 <= s <= 1.0 and 0.0 <= u <= 1.0",
           "the crossing test closed at both ends: a crossing through a shared node counted "
           "twice", G_CONTACT),
    Mutant("conservative_end_counted", "spinweb_fe/fe/contact/crossing.py",
           "if s == 1.0 or u == 1.0:", "if s == 2.0 or u == 2.0:",
           "the conservative test counts a meeting exactly at an element's far end too",
           G_CONTACT),
    Mutant("conservative_flat_never", "spinweb_fe/fe/contact/crossing.py",
           "if max(max(abs(v0), abs(v1)), max(abs(v2), abs(v3))) <= tol:",
           "if max(max(abs(v0), abs(v1)), max(abs(v2), abs(v3))) < 0.0:",
           "the conservative test (sep) never looks at a pair whose V stays at round-off",
           ("tests/test_crossing_conservative.py",)),
    Mutant("certificate_turn_halved", "spinweb_fe/fe/contact/bounds.py",
           "dth * dth / 8.0 + abs(dth) ** 3 / 3.0, abs(dth) / 4.0)",
           "dth * dth / 16.0 + abs(dth) ** 3 / 3.0, abs(dth) / 4.0)",
           "separation certificates: the frame's turn departs half as far from its chord",
           G_CONTACT),
    Mutant("certificate_own_dropped", "spinweb_fe/fe/contact/bounds.py",
           "dth * dth / 8.0 + abs(dth) ** 3 / 3.0, abs(dth) / 4.0)",
           "dth * dth / 8.0 + abs(dth) ** 3 / 3.0, 0.0)",
           "separation certificates: a node's own displacement turned with the frame left out",
           G_CONTACT),
    Mutant("draw_normal_unclipped_above", "spinweb_fe/sweep/draws.py",
           "return min(max(x, p.get(\"low\", -math.inf)), p.get(\"high\", math.inf))",
           "return max(x, p.get(\"low\", -math.inf))",
           "a clipped normal draw not clipped at its high end", G_SWEEP),
    Mutant("draw_choice_never_last", "spinweb_fe/sweep/draws.py",
           "return p[\"values\"][int(rng.integers(len(p[\"values\"])))]",
           "return p[\"values\"][int(rng.integers(len(p[\"values\"]) - 1))]",
           "a choice draw never takes the last value", G_SWEEP),
    Mutant("design_bracket_sides_swapped", "spinweb_fe/sweep/design.py",
           "[((a, b) if a.feasible else (b, a))", "[((a, b) if b.feasible else (b, a))",
           "the design's bisection given the infeasible end of each scanned bracket as the "
           "feasible one", G_SWEEP),
    Mutant("gci_bisection_wrong_side", "spinweb_fe/sweep/gci.py",
           "lo, hi = (mid, hi) if _g(mid, r21, r32) < ratio else (lo, mid)",
           "lo, hi = (lo, mid) if _g(mid, r21, r32) < ratio else (mid, hi)",
           "the observed order's bisection keeps the wrong half", G_SWEEP),
    Mutant("pass_rate_interval_of_failures", "spinweb_fe/sweep/report.py",
           "low, high = wilson(passes, n)", "low, high = wilson(n - passes, n)",
           "a sweep's pass-rate interval from the failures' count", G_SWEEP),
    Mutant("robust_interval_of_failures", "spinweb_fe/sweep/verify.py",
           "low, high = wilson(k, n)", "low, high = wilson(n - k, n)",
           "a robust design's pass-rate interval from the failures' count", G_SWEEP),
    Mutant("robust_worst_largest_margin", "spinweb_fe/sweep/verify.py",
           "worst = min(points, key=lambda p: p.margin)",
           "worst = max(points, key=lambda p: p.margin)",
           "a robust design names its best member as the worst", G_SWEEP),
    Mutant("brake_work_as_dissipation", "spinweb_fe/fe/layout.py",
           'Term("brake_work", -1, "J",', 'Term("brake_work", 1, "J",',
           "the energy balance adds the devices' work as if it were dissipated", G_REST),
    Mutant("balance_first_arm_only", "spinweb_fe/record/energy.py",
           "(value.sum(axis=1) if value.ndim == 2 else value)",
           "(value[:, 0] if value.ndim == 2 else value)",
           "the energy balance counts a per-arm term of the first arm only", G_REST),
    Mutant("free_hub_row_new_momentum", "spinweb_fe/fe/hub/body.py",
           "lm = M * cross(X, vm) + 0.5 * (rs.momentum + bk.Pi)",
           "lm = M * cross(X, vm) + bk.Pi",
           "a free hub's recorded angular momentum from its new half step only", G_REST),
    Mutant("free_hub_row_new_rate", "spinweb_fe/fe/hub/body.py",
           "return 0.5 * (bk.rate_old + bk.rate_new), ke,",
           "return bk.rate_new, ke,",
           "a free hub's recorded rate from its new half step only", G_REST),
    Mutant("coil_pull_axial_part_kept", "spinweb_fe/fe/coil/levels.py",
           "out = dx * (rx - h * ax[0]) + dy * (ry - h * ax[1]) + dz * (rz - h * ax[2])",
           "out = dx * rx + dy * ry + dz * rz",
           "the coil's pull on a free hub measured along the node's offset, its axial part "
           "kept", G_REST),
    Mutant("bundles_open_at_a_length", "spinweb_fe/fe/coil/bundles.py",
           "due = free_length(coil, cs, k) >= coil.bundle_value * span - 1e-12 * span",
           "due = free_length(coil, cs, k) >= coil.bundle_value - 1e-12 * span",
           "two-stage bundles open when the paid-out length reaches the share as metres",
           G_REST),
    Mutant("bundles_open_after_their_time", "spinweb_fe/fe/coil/bundles.py",
           "due = t >= coil.bundle_value", "due = t > coil.bundle_value",
           "timed bundles open a step after their time", G_REST),
    Mutant("audit_restart_forgets_skin", "spinweb_fe/record/crossings.py",
           "self.skin = float(np.asarray(memory.get(\"skin\", [self.skin])).ravel()[0])",
           "self.skin = self.base_skin",
           "a restarted crossing audit starts again from its first skin", G_REST),
    Mutant("audit_restart_forgets_build_step", "spinweb_fe/record/crossings.py",
           "self._built_at = int(np.asarray(memory.get(\"built_at\", [0])).ravel()[0])",
           "self._built_at = 0",
           "a restarted crossing audit forgets when its list was built", G_REST),
    Mutant("audit_no_rebuild_on_release", "spinweb_fe/record/crossings.py",
           "if moved or not np.array_equal(k.fronts, state.coil.front):",
           "if moved:",
           "the crossing audit keeps its list when a level is released", G_REST),
    Mutant("trial_kernel_shares_arrays", "spinweb_fe/record/feature.py",
           "            return v.copy()\n", "            return v\n",
           "a feature's trial kernel shares its arrays with the run's", G_REST),
    Mutant("rate_timed_on_the_runs_features", "spinweb_fe/run/loop.py",
           "own = copy.deepcopy(features, {id(model): model})", "own = features",
           "the estimate's timed steps serve the run's own features (its list rebuilt "
           "ahead of the run)", ("tests/test_estimate.py",)),
    Mutant("cells_keep_the_outer_face", "spinweb_fe/record/linking.py",
           "cycles = [tail[w] for w, a in zip(walks, area) if a > area_tol]",
           "cycles = [tail[w] for w, a in zip(walks, area) if abs(a) > area_tol]",
           "the linking check's cells include the web's outer face", LINK_TESTS),
    Mutant("hub_reaction_work_new_rate", "spinweb_fe/fe/contact/failsafe.py",
           "work_hub = inertia[0] * dw * (h0.rate[0] + rate[0] + dw) * 0.5",
           "work_hub = inertia[0] * dw * (rate[0] + rate[0] + dw) * 0.5",
           "the fixed hub's reaction work paired with its new half-step rate only",
           G_HUB_WORK),
    Mutant("verdict_plot_failure_at_start", "spinweb_fe/post/verdict_plot.py",
           "ax.axvline(crit.time, color=colour, ls=\":\", lw=1.2)",
           "ax.axvline(0.0 * crit.time, color=colour, ls=\":\", lw=1.2)",
           "the verdict plots draw a criterion's first failure at the run's start",
           ("tests/test_plot.py",)),
)


@dataclass
class Outcome:
    id: str
    verdict: str  # assertion | energy stop | error | timeout | SURVIVED | not applicable
    killed_by: list = field(default_factory=list)
    tests_run: int = 0
    seconds: float = 0.0
    recompiled: int | None = None
    note: str = ""


def make_copy(dest: Path) -> Path:
    copy = dest / "spinweb"
    shutil.copytree(ROOT, copy, ignore=IGNORE, symlinks=True)
    return copy


def environment(copy: Path, cache: Path) -> dict:
    env = dict(os.environ)
    env.update(PYTHONPATH=str(copy), NUMBA_CACHE_DIR=str(cache), PYTHONDONTWRITEBYTECODE="1",
               MPLBACKEND="Agg", SPINWEB_THREADS="1",
               SPINWEB_MUTATION_COPY="1")  # the copy's mutant has, by design, no target
    return env


def check_imports(copy: Path, env: dict):
    """The copy's packages, not the working tree's (editable install), must be imported."""
    code = "import spinweb_fe, meshgen; print(spinweb_fe.__file__); print(meshgen.__file__)"
    out = subprocess.run([sys.executable, "-c", code], cwd=copy, env=env, text=True,
                         capture_output=True, check=True).stdout.split()
    bad = [p for p in out if not Path(p).resolve().is_relative_to(copy.resolve())]
    if bad:
        raise SystemExit(f"mutate: the copy is not what Python imports: {bad}")


def classify(case) -> str | None:
    """'assertion', 'energy stop' or 'error' for a failed junit testcase, None if it passed."""
    bad = case.find("failure")
    kind = "failure"
    if bad is None:
        bad, kind = case.find("error"), "error"
    if bad is None:
        return None
    text = (bad.get("message") or "") + "\n" + (bad.text or "")
    if "energy balance off by" in text:
        return "energy stop"
    if kind == "failure" and ("AssertionError" in text or (bad.get("message") or "")
                              .lstrip().startswith("assert")):
        return "assertion"
    return "error"


def run_tests(copy: Path, env: dict, tests, xml: Path, timeout: float):
    """Run pytest on ``tests`` in the copy; {test id: classification or None}, or None on
    a timeout."""
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "not slow",
           f"--junitxml={xml}", *tests]
    try:
        subprocess.run(cmd, cwd=copy, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None
    if not xml.exists():
        return {}
    out = {}
    for case in ET.parse(xml).getroot().iter("testcase"):
        if case.find("skipped") is not None:
            continue
        name = f"{case.get('classname', '').replace('.', '/')}.py::{case.get('name')}"
        out[name] = classify(case)
    return out


def cache_files_since(cache: Path, t0: float) -> int:
    return sum(1 for p in cache.rglob("*") if p.suffix in (".nbi", ".nbc")
               and p.stat().st_mtime >= t0)


def run_mutant(m: Mutant, copy: Path, work: Path, base_cache: Path, baseline_failed: set,
               timeout: float) -> Outcome:
    src = copy / m.path
    text = src.read_text()
    if text.count(m.old) != 1:
        return Outcome(m.id, "not applicable",
                       note=f"snippet found {text.count(m.old)} times in {m.path}")
    cache = work / f"cache_{m.id}"
    shutil.copytree(base_cache, cache)
    stat = src.stat()
    t0 = time.time()
    src.write_text(text.replace(m.old, m.new))
    try:
        results = run_tests(copy, environment(copy, cache), m.tests, work / f"{m.id}.xml",
                            timeout)
    finally:
        src.write_text(text)
        os.utime(src, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    seconds = time.time() - t0
    recompiled = cache_files_since(cache, t0) if m.path.startswith("spinweb_fe/fe/") else None
    shutil.rmtree(cache, ignore_errors=True)
    if results is None:
        return Outcome(m.id, "timeout", seconds=seconds, recompiled=recompiled)
    failed = {k: v for k, v in results.items() if v and k not in baseline_failed}
    out = Outcome(m.id, "SURVIVED", tests_run=len(results), seconds=seconds,
                  recompiled=recompiled)
    for kind in ("assertion", "energy stop", "error"):
        hit = sorted(k for k, v in failed.items() if v == kind)
        if hit:
            out.verdict, out.killed_by = kind, hit
            break
    if out.verdict == "SURVIVED" and recompiled == 0:
        out.note = "no cache file written: stale numba cache?"
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", help="comma-separated mutant ids")
    ap.add_argument("--list", action="store_true", help="list the mutants and exit")
    ap.add_argument("--timeout", type=float, default=900.0, help="per mutant [s]")
    ap.add_argument("--report", default=str(ROOT / "out" / "mutation" / "report.json"))
    args = ap.parse_args(argv)
    ids = [m.id for m in MUTANTS]
    assert len(set(ids)) == len(ids), "duplicate mutant ids"
    chosen = list(MUTANTS)
    if args.only:
        want = args.only.split(",")
        unknown = sorted(set(want) - set(ids))
        if unknown:
            raise SystemExit(f"mutate: unknown mutant(s) {unknown} (valid: {', '.join(ids)})")
        chosen = [m for m in MUTANTS if m.id in want]
    if args.list:
        for m in MUTANTS:
            print(f"{m.id:34s} {'issue' if m.issue else 'own':5s} {m.path}: {m.what}")
        return 0
    canary = MUTANTS[0]
    if canary not in chosen:
        chosen.insert(0, canary)
    with tempfile.TemporaryDirectory(prefix="spinweb-mutate-") as tmp:
        work = Path(tmp)
        copy = make_copy(work)
        base_cache = work / "cache_base"
        env = environment(copy, base_cache)
        check_imports(copy, env)
        tests = sorted({t for m in chosen for t in m.tests})
        print(f"baseline: {len(tests)} test files on the unmutated copy in {copy} ...",
              flush=True)
        t0 = time.time()
        base = run_tests(copy, env, tests, work / "baseline.xml", args.timeout * 2)
        if base is None:
            raise SystemExit("mutate: the baseline run timed out")
        baseline_failed = {k for k, v in base.items() if v}
        print(f"baseline: {len(base)} tests, {len(baseline_failed)} failing (ignored below)"
              f", {time.time() - t0:.0f} s", flush=True)
        for k in sorted(baseline_failed):
            print(f"  baseline failure: {k}")
        outcomes = []
        for m in chosen:
            o = run_mutant(m, copy, work, base_cache, baseline_failed, args.timeout)
            outcomes.append(o)
            first = o.killed_by[0] if o.killed_by else ""
            extra = f" (+{len(o.killed_by) - 1})" if len(o.killed_by) > 1 else ""
            rc = "" if o.recompiled is None else f", recompiled {o.recompiled}"
            print(f"{m.id:34s} {o.verdict:14s} {o.seconds:5.0f} s{rc}  {first}{extra} "
                  f"{o.note}", flush=True)
            if m is canary and o.verdict != "assertion":
                raise SystemExit("mutate: the canary survived: the copy is not under test "
                                 "(or a stale cache was used)")
    by_id = {m.id: m for m in MUTANTS}
    issue = [o for o in outcomes if by_id[o.id].issue]
    own = [o for o in outcomes if not by_id[o.id].issue and o.verdict != "not applicable"]
    ok_issue = sum(o.verdict == "assertion" for o in issue)
    ok_own = sum(o.verdict == "assertion" for o in own)
    rate = ok_own / len(own) if own else 1.0
    print(f"\nissue's mutants killed by an assertion: {ok_issue}/{len(issue)}")
    print(f"own mutants killed by an assertion: {ok_own}/{len(own)} ({100 * rate:.0f} %)")
    for o in outcomes:
        if o.verdict != "assertion":
            print(f"  {o.id}: {o.verdict} {o.note}")
    report = Path(args.report)
    report.parent.mkdir(parents=True, exist_ok=True)
    report.write_text(json.dumps({"mutants": [asdict(m) | asdict(o) for m, o in
                                              zip([by_id[o.id] for o in outcomes], outcomes)],
                                  "issue_killed": [ok_issue, len(issue)],
                                  "own_killed": [ok_own, len(own)]}, indent=1))
    print(f"report: {report}")
    full = len(issue) == sum(m.issue for m in MUTANTS)
    return 0 if ok_issue == len(issue) and rate >= 0.9 and (full or args.only) else 1


if __name__ == "__main__":
    sys.exit(main())

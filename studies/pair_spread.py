"""Would an element-level schedule shorten the audit's read of its list? (issue #42)

    python -m studies.pair_spread [TIMES ...]      # default 0.05 0.15 0.3 0.6 [s]

The audit reads every listed pair's certificate each step. An element-level schedule
would read an element's pairs only when its motion reaches the least certificate of
those pairs. Such a schedule must still read every pair of each element that one of its
pairs needs.

For the paper's feedback web folded with a 5 mm layer gap, this study runs the audit to
each time and stops there. It then counts:

- the pairs the next step would look at: level less the elements' sums and the last
  step's bounds, at or below the least separation;
- the elements of those pairs;
- all the pairs of those elements, which is what the schedule would read.

Writes benchmarks/results/pair_spread.json. No timing.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from benchmarks.common import machine
from benchmarks.contact_cost import GAP, MODES, ROOT
from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.fe.contact.touch import SEP
from spinweb_fe.run.features import features_of
from spinweb_fe.run.loop import Schedule, simulate

OUT = ROOT / "benchmarks" / "results" / "pair_spread.json"


def spread(end: float) -> dict:
    case = case_mod.load(ROOT / "cases" / "paper_feedback_web.toml",
                         [*GAP, *MODES["audit"], f"time.end={end}"])
    scene = prepare(case)
    feats = features_of(scene.model, scene.state, case)
    simulate(scene.model, scene.control, scene.state, scene.dt, Schedule(end, 1e-3),
             features=feats)
    k = {f.name: f for f in feats}["crossings"].kernel_data
    mo = k.motion
    pairs = np.asarray(k.pairs)
    e, f = pairs[:, 0], pairs[:, 1]
    after = mo.cum + mo.elem  # the sums after one more step like the last
    looked = k.level - after[e] - after[f] <= SEP * mo.scale[0]
    needed = np.zeros(len(mo.cum), bool)
    needed[e[looked]] = needed[f[looked]] = True
    read = needed[e] | needed[f]
    return {"t_s": end, "listed": int(len(pairs)), "looked_next": int(looked.sum()),
            "their_elements": int(needed.sum()), "elements": int(len(needed)),
            "pairs_of_those_elements": int(read.sum()), "share_of_list": float(read.mean())}


def main(argv=None):
    times = [float(x) for x in (sys.argv[1:] if argv is None else argv)] or \
        [0.05, 0.15, 0.3, 0.6]
    rows = []
    for t in times:
        rows.append(spread(t))
        r = rows[-1]
        print(f"t = {t} s: {r['listed']} listed, {r['looked_next']} looked at next step, "
              f"{r['their_elements']} of {r['elements']} elements, "
              f"{r['pairs_of_those_elements']} of their pairs ({100 * r['share_of_list']:.0f} %)")
    Path(OUT).write_text(json.dumps({"machine": machine(), "rows": rows}, indent=1))
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()

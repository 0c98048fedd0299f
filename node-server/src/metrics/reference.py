"""Reference values for the Rust metrics tests (node-server/src/metrics/tests.rs).

Reads scenarios.json (the same inputs the Rust tests read) and prints, per scenario, the CLEAR MOT
and identity metrics from py-motmetrics and the GOSPA from Stone Soup, plus per-target values
derived from motmetrics' event table.

    python -m venv venv && venv/bin/pip install motmetrics==1.4.0 stonesoup==1.9.1
    venv/bin/python reference.py

Distances are plain Euclidean (no max_d2 squaring, no IoU): a pair farther than the threshold is
NaN, i.e. not allowed to match, as motmetrics' `norm2squared_matrix` does with `max_d2`.
"""
import datetime
import json
import os

import numpy as np
import motmetrics as mm
from stonesoup.metricgenerator.ospametric import GOSPAMetric
from stonesoup.types.state import State

HERE = os.path.dirname(os.path.abspath(__file__))


def distances(truth, hyps, threshold):
    d = np.full((len(truth), len(hyps)), np.nan)
    for i, (_, p) in enumerate(truth):
        for j, (_, q) in enumerate(hyps):
            dist = float(np.linalg.norm(np.asarray(p) - np.asarray(q)))
            if dist <= threshold:
                d[i, j] = dist
    return d


def clear_and_identity(sc):
    acc = mm.MOTAccumulator(auto_id=True)
    for f in sc["frames"]:
        acc.update([o for o, _ in f["truth"]], [h for h, _ in f["hyps"]],
                   distances(f["truth"], f["hyps"], sc["threshold"]))
    names = ["mota", "motp", "idf1", "idp", "idr", "idtp", "num_switches", "num_fragmentations",
             "mostly_tracked", "partially_tracked", "mostly_lost", "num_false_positives",
             "num_misses", "num_matches", "num_objects", "num_predictions"]
    summary = mm.metrics.create().compute(acc, metrics=names, name="x")
    run = {n: summary[n]["x"].item() for n in names}
    ev = acc.mot_events
    ev = ev[ev.Type.isin(["MATCH", "SWITCH", "MISS", "FP"])]  # motmetrics' "noraw" events
    per = {}
    for o in sorted({o for f in sc["frames"] for o, _ in f["truth"]}):
        e = ev[ev.OId == o]
        seen = len(e)
        tracked = int((e.Type != "MISS").sum())
        hyps = []
        for h in e[e.Type != "MISS"].HId:
            if int(h) not in hyps:
                hyps.append(int(h))
        per[o] = {"frames": seen, "tracked": tracked, "id_switches": int((e.Type == "SWITCH").sum()),
                  "hyp_ids": hyps}
    # motmetrics' fragmentation count, per object (its num_fragmentations loop, one object at a time)
    for o in per:
        e = ev[ev.OId == o]
        notmiss = e[e.Type != "MISS"]
        frag = 0
        if len(notmiss):
            d = e.loc[notmiss.index[0]:notmiss.index[-1]].Type.apply(lambda x: 1 if x == "MISS" else 0).diff()
            frag = int(d[d == 1].count())
        per[o]["fragmentations"] = frag
    # The hypothesis each truth got in the global identity assignment (IDF1), when it shares frames.
    df_map = mm.metrics.events_to_df_map(acc.events)
    ga = mm.metrics.id_global_assignment(df_map)
    ocs, hcs, tps = mm.metrics.extract_counts_from_df_map(df_map)
    oids, hids = sorted(ocs), sorted(hcs)
    for r, c in zip(ga["rids"], ga["cids"]):
        if r < len(oids) and c < len(hids) and tps.get((oids[r], hids[c]), 0) > 0:
            per[int(oids[r])]["identity"] = int(hids[c])
    return run, per


def gospa(sc):
    base = datetime.datetime(2024, 1, 1)
    meas, meas_ids, truth, truth_ids = [], [], [], []
    for f in sc["frames"]:
        ts = base + datetime.timedelta(seconds=f["t"])
        for o, p in f["truth"]:
            truth.append(State(np.array(p, dtype=float).reshape(-1, 1), timestamp=ts))
            truth_ids.append(o)
        for h, p in f["hyps"]:
            meas.append(State(np.array(p, dtype=float).reshape(-1, 1), timestamp=ts))
            meas_ids.append(h)
    g = GOSPAMetric(c=sc["gospa_c"], p=sc["gospa_p"])
    out = g.compute_over_time(meas, meas_ids, truth, truth_ids)
    values = [m.value for m in out.value]
    return {k: float(np.mean([v[k] for v in values])) for k in ("distance", "localisation", "missed", "false")} | {"frames": len(values)}


def rust(sc, run, per, g):
    """The scenario's expected values as the Rust tests' `Expected` literal."""
    f = lambda v: repr(float(v))
    targets = ", ".join(
        "({}, {}, {}, {}, {}, &{}, {})".format(o, v["frames"], v["tracked"], v["id_switches"], v["fragmentations"],
                                              v["hyp_ids"], "Some({})".format(v["identity"]) if "identity" in v else "None")
        for o, v in per.items())
    return f"""Expected {{
    name: "{sc['name']}",
    mota: {f(run['mota'])},
    motp_m: {f(run['motp'])},
    idf1: {f(run['idf1'])},
    idp: {f(run['idp'])},
    idr: {f(run['idr'])},
    idtp: {int(run['idtp'])},
    id_switches: {run['num_switches']},
    fragmentations: {run['num_fragmentations']},
    mostly_tracked: {run['mostly_tracked']},
    partially_tracked: {run['partially_tracked']},
    mostly_lost: {run['mostly_lost']},
    false_positives: {run['num_false_positives']},
    misses: {run['num_misses']},
    matches: {run['num_matches']},
    objects: {run['num_objects']},
    predictions: {run['num_predictions']},
    gospa: [{f(g['distance'])}, {f(g['localisation'])}, {f(g['missed'])}, {f(g['false'])}],
    gospa_frames: {g['frames']},
    // (id, frames, tracked, id switches, fragmentations, hypothesis ids, identity)
    targets: &[{targets}],
}},"""


if __name__ == "__main__":
    import stonesoup
    print(f"// py-motmetrics {mm.__version__}, Stone Soup {stonesoup.__version__}")
    for sc in json.load(open(os.path.join(HERE, "scenarios.json"))):
        run, per = clear_and_identity(sc)
        print(rust(sc, run, per, gospa(sc)))

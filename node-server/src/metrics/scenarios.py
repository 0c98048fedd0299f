"""Writes scenarios.json: the inputs of the metrics reference tests (read by reference.py and by
the Rust tests). Four small runs covering an id switch, misses, false positives, a hypothesis
beyond the threshold, fragmentation, the coverage classes, crossing targets whose previous
matches are kept, 3D positions, a duplicate track, empty frames and an assignment that must
prefer more pairs over a shorter distance.

    python scenarios.py
"""
import json
import os


def r(v):
    return [round(x, 3) for x in v]


sc = []
# A: two walkers; an id switch on truth 1, a miss and an out-of-threshold hypothesis on truth 2, a false positive.
fr = []
for k in range(6):
    truth = [[1, r([k*0.5, 0.0])], [2, r([k*0.5, 3.0])]]
    hyps = []
    off1 = [(0.1, 0.0), (0.2, 0.1), (0.0, 0.3), (-0.1, 0.2), (0.3, -0.2), (0.05, 0.05)][k]
    hyps.append([10 if k < 4 else 11, r([k*0.5 + off1[0], off1[1]])])
    if k == 2:
        pass  # truth 2 missed
    elif k == 4:
        hyps.append([20, r([k*0.5 + 1.2, 3.9])])  # 1.5 m away: miss + false positive
    else:
        off2 = [(0.2, 0.2), (-0.3, 0.1), None, (0.1, -0.4), None, (0.0, 0.6)][k]
        hyps.append([20, r([k*0.5 + off2[0], 3.0 + off2[1]])])
    if k in (1, 2):
        hyps.append([30, [10.0, 10.0]])
    fr.append({"t": round(k*0.2, 3), "truth": truth, "hyps": hyps})
sc.append({"name": "switch_fp_miss", "dim": 2, "threshold": 1.0, "gospa_c": 2.0, "gospa_p": 1, "frames": fr})

# B: fragmentation and coverage classes.
fr = []
for k in range(10):
    x = k*0.4
    truth = [[5, r([x, 1.0])], [9, r([x, -2.0])], [3, r([4.0, 4.0 - 0.1*k])]]
    if k >= 4:
        truth.append([6, r([-3.0, x])])
    hyps = []
    # truth 5: h7 on 0-2, missed 3-4, h7 on 5-6, missed 7, h8 on 8-9 (switch after the gap)
    if k in (0, 1, 2, 5, 6):
        hyps.append([7, r([x + 0.1*((k % 3) - 1), 1.2])])
    if k in (8, 9):
        hyps.append([8, r([x - 0.2, 0.9])])
    if k == 7:
        hyps.append([7, r([x, 2.5])])  # 1.5 m off: miss and a false positive
    # truth 9 tracked 3 of 10 frames (partially tracked)
    if k in (2, 3, 6):
        hyps.append([12, r([x + 0.3, -2.1])])
    # truth 3 tracked all but one frame (mostly tracked)
    if k != 4:
        hyps.append([4, r([4.0 + 0.05*k, 4.0 - 0.1*k + 0.2])])
    fr.append({"t": round(k*0.2, 3), "truth": truth, "hyps": hyps})
sc.append({"name": "fragmentation", "dim": 2, "threshold": 1.0, "gospa_c": 2.0, "gospa_p": 1, "frames": fr})

# C: crossing walkers; the tracker swaps its ids at the crossing.
fr = []
for k in range(9):
    s = k*0.5
    t1 = [s, s]; t2 = [s, 4.0 - s]
    truth = [[1, r(t1)], [2, r(t2)]]
    # hyp 100 follows truth 1 until the middle, then truth 2; hyp 200 the other way round.
    if k <= 4:
        a = [t1[0] + 0.05, t1[1] - 0.1]; b = [t2[0] - 0.05, t2[1] + 0.1]
    else:
        a = [t2[0] + 0.1, t2[1] + 0.05]; b = [t1[0] - 0.1, t1[1] + 0.05]
    if k == 3:
        # near the crossing: each hypothesis is closer to the other truth, but its previous match
        # is still within the threshold, so it is kept (no switch yet).
        a = [t2[0] + 0.0, t2[1] - 0.3]; b = [t1[0], t1[1] + 0.3]
    hyps = [[100, r(a)], [200, r(b)]]
    fr.append({"t": round(k*0.2, 3), "truth": truth, "hyps": hyps})
sc.append({"name": "crossing", "dim": 2, "threshold": 1.0, "gospa_c": 2.0, "gospa_p": 1, "frames": fr})

# D: 3D, ids out of order, a late truth, a duplicate track, an empty frame, a frame with only
# hypotheses, and a hypothesis near two truths (the assignment must match both).
fr = []
for k in range(8):
    z = 1.7
    truth = []
    if k != 5 and k != 6:
        truth += [[42, r([1.0, 1.0 + 0.3*k, z])], [7, r([1.8, 1.0 + 0.3*k, z])]]
    if k >= 3 and k != 5 and k != 6:
        truth.append([100, r([5.0, 0.2*k, 1.0])])
    hyps = []
    if k == 5:
        pass  # nothing at all
    elif k == 6:
        hyps.append([3, [9.0, 9.0, 1.0]])
    else:
        # hyp 1 sits next to 42 but also reaches 7; hyp 2 only reaches 42, and barely: the
        # assignment must pair 1 with 7 and 2 with 42 (more pairs beat a shorter distance).
        hyps.append([1, r([1.05, 1.0 + 0.3*k, z + 0.1])])
        if k % 2 == 0:
            hyps.append([2, r([0.15, 1.0 + 0.3*k, z - 0.2])])
        if k >= 3:
            hyps.append([5, r([5.1, 0.2*k + 0.1, 1.2])])
        if k >= 4:
            hyps.append([6, r([5.3, 0.2*k - 0.2, 0.9])])  # duplicate of the late truth
    fr.append({"t": round(k*0.2, 3), "truth": truth, "hyps": hyps})
sc.append({"name": "three_d_mixed", "dim": 3, "threshold": 1.0, "gospa_c": 2.0, "gospa_p": 2, "frames": fr})
# One frame per line, so that a change reads as a diff of frames.
lines = []
for s in sc:
    head = {k: v for k, v in s.items() if k != "frames"}
    frames = ",\n".join("   " + json.dumps(f) for f in s["frames"])
    lines.append(json.dumps(head)[:-1] + ', "frames": [\n' + frames + "\n ]}")
with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "scenarios.json"), "w") as out:
    out.write("[\n " + ",\n ".join(lines) + "\n]\n")

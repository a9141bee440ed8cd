#!/usr/bin/python3
"""How predictable is the number of agents in a scenario's region from the map alone?

Why: full mode's goal asks each val scenario's generated agent count to land within 30 % of the log's; this measures
how far any predictor that sees only the map can get (docs/model.md, "How far the map alone predicts the count").

Data: ../shared/data/womd/json/{train,val} (GPUDrive/Nocturne JSON, 91 frames, current frame 10).
Count (mirrors offline/eval/placed_agents.cc log_placed_agents + engine/map/focus.cc):
  at frame 10, tracks of type vehicle/pedestrian/cyclist, valid, within 100 m of the centre.
  centre = SDC (metadata.sdc_track_index) position at frame 10; files without metadata have no SDC,
  and the project then uses scenario_focus(): mean position of every track valid at frame 10.
  The SDC itself is counted (as log_placed_agents does with with_sdc=true, i.e. under the default --sdc model).
Map features: everything within R=100 m of the centre (segments by midpoint, polygons by centroid).

Usage: /usr/bin/python3 training/analysis/count_predictability.py [--data ../shared/data/womd/json] --out DIR
  (writes DIR/features.json, a cache, and DIR/results.md; a few seconds)
"""
import glob
import json
import math
import os
import sys

import numpy as np

DATA = OUT = ""  # set from the command line in main()
R = 100.0
NOW = 10
LATER = 90
AGENT_TYPES = {"vehicle", "pedestrian", "cyclist"}


def centre_at(d, frame):
    """SDC position at `frame` (None if SDC named but invalid there), else mean of valid tracks (focus.cc)."""
    md = d.get("metadata") or {}
    sdc = md.get("sdc_track_index", -1)
    objs = d["objects"]
    if sdc is not None and 0 <= sdc < len(objs):
        o = objs[sdc]
        if o["valid"][frame]:
            p = o["position"][frame]
            return (p["x"], p["y"]), True
        return None, True
    pts = [(o["position"][frame]["x"], o["position"][frame]["y"]) for o in objs if o["valid"][frame]]
    if not pts:
        return None, False
    a = np.array(pts)
    return tuple(a.mean(axis=0)), False


def count_at(d, frame, c):
    n = 0
    for o in d["objects"]:
        if o["type"] not in AGENT_TYPES or not o["valid"][frame]:
            continue
        p = o["position"][frame]
        if math.hypot(p["x"] - c[0], p["y"] - c[1]) <= R:
            n += 1
    return n


def poly_len_within(g, c):
    """Length of the polyline's segments whose midpoint lies within R of c; points within R."""
    a = np.array([[p["x"], p["y"]] for p in g], dtype=float)
    if len(a) == 0:
        return 0.0, 0
    inside_pts = int((np.hypot(a[:, 0] - c[0], a[:, 1] - c[1]) <= R).sum())
    if len(a) < 2:
        return 0.0, inside_pts
    mid = 0.5 * (a[1:] + a[:-1])
    seg = np.hypot(*(a[1:] - a[:-1]).T)
    m = np.hypot(mid[:, 0] - c[0], mid[:, 1] - c[1]) <= R
    return float(seg[m].sum()), inside_pts


def polygon_area(g):
    a = np.array([[p["x"], p["y"]] for p in g], dtype=float)
    if len(a) < 3:
        return 0.0
    x, y = a[:, 0], a[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def features(d, c):
    f = {k: 0.0 for k in FEATURES}
    has_sub = False
    for r in d["roads"]:
        t = r["type"]
        g = r["geometry"]
        if t in ("lane", "road_edge", "road_line"):
            L, npts = poly_len_within(g, c)
            if npts == 0 and L == 0:
                continue
            if t == "lane":
                f["lane_km"] += L / 1000
                f["n_lanes"] += 1
                f["n_lane_pts"] += npts
                mid = r.get("map_element_id")
                if mid is not None:
                    has_sub = True
                    if mid == 1:
                        f["freeway_lane_km"] += L / 1000
                    elif mid == 3:
                        f["bike_lane_km"] += L / 1000
                    else:
                        f["surface_lane_km"] += L / 1000
            elif t == "road_edge":
                f["road_edge_km"] += L / 1000
                f["n_road_edges"] += 1
            else:
                f["road_line_km"] += L / 1000
                f["n_road_line_pts"] += npts
        else:
            a = np.array([[p["x"], p["y"]] for p in g], dtype=float)
            if len(a) == 0:
                continue
            cen = a.mean(axis=0)
            if math.hypot(cen[0] - c[0], cen[1] - c[1]) > R:
                continue
            if t == "crosswalk":
                f["n_crosswalks"] += 1
                f["crosswalk_area"] += polygon_area(g)
            elif t == "driveway":
                f["n_driveways"] += 1
                f["driveway_area"] += polygon_area(g)
            elif t == "stop_sign":
                f["n_stop_signs"] += 1
            elif t == "speed_bump":
                f["n_speed_bumps"] += 1
    # Signalised lanes within R (tl_states position at the current frame)
    for v in (d.get("tl_states") or {}).values():
        try:
            x, y = v["x"][NOW], v["y"][NOW]
        except (KeyError, IndexError, TypeError):
            continue
        if x is not None and y is not None and math.hypot(x - c[0], y - c[1]) <= R:
            f["n_signal_lanes"] += 1
    if not has_sub:  # older files carry no lane subtype: all lane length counted as surface street
        f["surface_lane_km"] = f["lane_km"]
    f["has_lane_subtype"] = float(has_sub)
    return f


FEATURES = ["lane_km", "n_lanes", "n_lane_pts", "surface_lane_km", "freeway_lane_km", "bike_lane_km",
            "road_edge_km", "n_road_edges", "road_line_km", "n_road_line_pts", "n_crosswalks", "crosswalk_area",
            "n_driveways", "driveway_area", "n_stop_signs", "n_speed_bumps", "n_signal_lanes", "has_lane_subtype"]


def load(split):
    rows = []
    for fn in sorted(glob.glob(f"{DATA}/{split}/*.json")):
        with open(fn) as fh:
            d = json.load(fh)
        c, has_sdc = centre_at(d, NOW)
        assert c is not None, fn
        row = {"file": os.path.basename(fn), "split": split, "has_sdc": has_sdc, "count": count_at(d, NOW, c)}
        # later frame: region around the SDC (or focus) at frame 90, falling back to the SDC's last valid frame
        later = LATER
        c2, _ = centre_at(d, later)
        while c2 is None and later > NOW:
            later -= 1
            c2, _ = centre_at(d, later)
        row["later_frame"] = later
        row["count_later_moving"] = count_at(d, later, c2)   # region centred on the SDC at the later frame
        row["count_later_fixed"] = count_at(d, later, c)     # same region as at frame 10
        row["feat"] = features(d, c)
        rows.append(row)
        del d
    return rows


def hits(pred, y):
    pred = np.asarray(pred, float)
    y = np.asarray(y, float)
    return int((np.abs(pred - y) <= 0.3 * y).sum())


def design(rows):
    X = np.array([[r["feat"][k] for k in FEATURES] for r in rows], float)
    # log1p of the non-negative magnitudes (all but the indicator)
    X[:, :-1] = np.log1p(X[:, :-1])
    return X


def standardise(Xtr, Xva):
    mu = Xtr.mean(0)
    sd = Xtr.std(0)
    sd[sd == 0] = 1
    return (Xtr - mu) / sd, (Xva - mu) / sd


def ridge_fit_predict(Xtr, ytr, Xva, alpha):
    Ztr, Zva = standardise(Xtr, Xva)
    A = np.hstack([np.ones((len(Ztr), 1)), Ztr])
    P = alpha * np.eye(A.shape[1])
    P[0, 0] = 0
    w = np.linalg.solve(A.T @ A + P, A.T @ ytr) if alpha > 0 else np.linalg.lstsq(A, ytr, rcond=None)[0]
    return np.hstack([np.ones((len(Zva), 1)), Zva]) @ w, w


def knn_predict(Xtr, ytr, Xva, k):
    Ztr, Zva = standardise(Xtr, Xva)
    D = ((Zva[:, None, :] - Ztr[None, :, :]) ** 2).sum(-1)
    idx = np.argsort(D, axis=1)[:, :k]
    return ytr[idx].mean(1)


def loo(Xtr, ytr, fn):
    """Leave-one-out on train (more samples than the 41 val scenarios): predictions of log count."""
    out = np.empty(len(ytr))
    for i in range(len(ytr)):
        m = np.ones(len(ytr), bool)
        m[i] = False
        out[i] = fn(Xtr[m], ytr[m], Xtr[i:i + 1])[0]
    return out


def dist(a):
    a = np.asarray(a)
    return f"min {a.min()}, median {np.median(a):g}, max {a.max()}, mean {a.mean():.1f}"


def main():
    global DATA, OUT
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="../shared/data/womd/json", help="the WOMD JSON folder (train/ and val/)")
    ap.add_argument("--out", required=True, help="a folder for features.json and results.md (not the repository)")
    args = ap.parse_args()
    DATA, OUT = args.data, args.out
    if not os.path.isdir(os.path.join(DATA, "train")) or not os.path.isdir(os.path.join(DATA, "val")):
        sys.exit(f"count_predictability: {DATA} has no train/ and val/ folders")
    os.makedirs(OUT, exist_ok=True)
    cache = os.path.join(OUT, "features.json")
    if os.path.exists(cache):
        with open(cache) as fh:
            rows = json.load(fh)
    else:
        rows = load("train") + load("val")
        with open(cache, "w") as fh:
            json.dump(rows, fh)
    tr = [r for r in rows if r["split"] == "train"]
    va = [r for r in rows if r["split"] == "val"]
    ytr = np.array([r["count"] for r in tr], float)
    yva = np.array([r["count"] for r in va], float)
    L = []
    p = L.append
    p("# Predicting the number of agents in the 100 m region from the map alone\n")
    n_tr_nosdc = sum(not r["has_sdc"] for r in tr)
    n_va_nosdc = sum(not r["has_sdc"] for r in va)
    p(f"Data: {DATA} train ({len(tr)}) / val ({len(va)}). Count = vehicles+pedestrians+cyclists valid at "
      f"frame 10 within 100 m of the SDC at frame 10 (SDC included). {n_tr_nosdc + n_va_nosdc} files ({n_tr_nosdc} train, "
      f"{n_va_nosdc} val) carry no "
      "`metadata.sdc_track_index`; for them the centre is the project's `scenario_focus` fallback (mean of all "
      "tracks valid at frame 10). Hit = |pred - count| <= 0.3 * count, predictions rounded to an integer.\n")
    p("## 1. Count distribution\n")
    for name, rs in (("train", tr), ("val", va)):
        y = [r["count"] for r in rs]
        ys = [r["count"] for r in rs if r["has_sdc"]]
        yn = [r["count"] for r in rs if not r["has_sdc"]]
        p(f"- {name} (n={len(y)}): {dist(y)}; quartiles {np.percentile(y, 25):g} / {np.percentile(y, 75):g}")
        p(f"  - with SDC (n={len(ys)}): {dist(ys)}; focus fallback (n={len(yn)}): {dist(yn)}")
    p(f"\nval counts sorted: {sorted(int(v) for v in yva)}\n")

    p("## 2. Constant baselines (fit on train)\n")
    med = float(np.median(ytr))
    cands = np.arange(1, int(ytr.max()) + 1)
    tr_hits = np.array([hits(np.full(len(ytr), c), ytr) for c in cands])
    cbest = int(cands[tr_hits.argmax()])
    va_hits_all = np.array([hits(np.full(len(yva), c), yva) for c in cands])
    p(f"- train median c={med:g}: val hits {hits(np.full(len(yva), round(med)), yva)}/{len(yva)} "
      f"(train {hits(np.full(len(ytr), round(med)), ytr)}/{len(ytr)})")
    p(f"- c maximising train hits c={cbest} (train {tr_hits.max()}/{len(ytr)}): val hits "
      f"{hits(np.full(len(yva), cbest), yva)}/{len(yva)}")
    p(f"- (ceiling, not a fair baseline) best constant chosen on val: c={int(cands[va_hits_all.argmax()])}, "
      f"{va_hits_all.max()}/{len(yva)}\n")

    p("## 3. Map features -> log count\n")
    Xtr, Xva = design(tr), design(va)
    ltr, lva = np.log(ytr), np.log(yva)
    p("Features (within 100 m; log1p): " + ", ".join(FEATURES) + "\n")
    p("Per-feature Pearson r with log count (train / val):\n")
    p("| feature | r train | r val |\n|---|---|---|")
    for j, k in enumerate(FEATURES):
        def r_(x, y):
            return float(np.corrcoef(x, y)[0, 1]) if x.std() > 0 else float("nan")
        p(f"| {k} | {r_(Xtr[:, j], ltr):+.2f} | {r_(Xva[:, j], lva):+.2f} |")
    p("")
    models = [("OLS", lambda a, b, c: ridge_fit_predict(a, b, c, 0.0)[0]),
              ("ridge alpha=1", lambda a, b, c: ridge_fit_predict(a, b, c, 1.0)[0]),
              ("ridge alpha=10", lambda a, b, c: ridge_fit_predict(a, b, c, 10.0)[0]),
              ("ridge alpha=100", lambda a, b, c: ridge_fit_predict(a, b, c, 100.0)[0])]
    for k in (3, 5, 10, 20):
        models.append((f"kNN k={k}", lambda a, b, c, k=k: knn_predict(a, b, c, k)))
    # a one-feature model for reference
    one = FEATURES.index("lane_km")
    models.append(("OLS lane_km only", lambda a, b, c: ridge_fit_predict(a[:, [one]], b, c[:, [one]], 0.0)[0]))
    p(f"| model | val r (pred vs log count) | val R^2 (log) | val hits /{len(yva)} | train-LOO r | "
      f"train-LOO hits /{len(ytr)} |")
    p("|---|---|---|---|---|---|")
    for name, fn in models:
        pv = fn(Xtr, ltr, Xva)
        r = float(np.corrcoef(pv, lva)[0, 1])
        r2 = 1 - ((pv - lva) ** 2).sum() / ((lva - lva.mean()) ** 2).sum()
        pl = loo(Xtr, ltr, fn)
        rl = float(np.corrcoef(pl, ltr)[0, 1])
        p(f"| {name} | {r:+.2f} | {r2:+.2f} | {hits(np.round(np.exp(pv)), yva)} | {rl:+.2f} | "
          f"{hits(np.round(np.exp(pl)), ytr)} |")
    _, w = ridge_fit_predict(Xtr, ltr, Xva, 10.0)
    p("\nRidge alpha=10 standardised coefficients: " +
      ", ".join(f"{k} {w[j + 1]:+.2f}" for j, k in sorted(enumerate(FEATURES), key=lambda t: -abs(w[t[0] + 1]))))
    p(f"\nResidual spread: std of log count on val = {lva.std():.2f} (a factor of {math.exp(lva.std()):.2f}); "
      f"a 30 % window is log(1.3)={math.log(1.3):.2f} up / log(0.7)={math.log(0.7):.2f} down.\n")

    p(f"Noise: with {len(yva)} val scenarios one hit is {100 / len(yva):.1f} %; at a 30 % hit rate the binomial s.e. is "
      f"about +-{math.sqrt(0.3 * 0.7 * len(yva)):.0f} hits, so val differences of a few hits between models are not "
      f"meaningful; the train leave-one-out column ({len(ytr)}) is the steadier comparison.\n")
    p("## 4. Within-log variation of the count (val)\n")
    later = [r["later_frame"] for r in va]
    mov = np.array([r["count_later_moving"] for r in va], float)
    fix = np.array([r["count_later_fixed"] for r in va], float)
    p(f"Later frame = 90 for {sum(f == 90 for f in later)}/{len(va)} (else the centre's last valid frame: "
      f"{sorted(f for f in later if f != 90)}).")
    p(f"- region re-centred on the SDC at the later frame: {hits(mov, yva)}/{len(yva)} within 30 % of the frame-10 count; "
      f"median |ratio-1| {np.median(np.abs(mov / yva - 1)):.2f}; r(log) {np.corrcoef(np.log(np.maximum(mov, 1)), lva)[0, 1]:+.2f}")
    p(f"- same region as frame 10: {hits(fix, yva)}/{len(yva)} within 30 %; median |ratio-1| "
      f"{np.median(np.abs(fix / yva - 1)):.2f}; r(log) {np.corrcoef(np.log(np.maximum(fix, 1)), lva)[0, 1]:+.2f}")
    trm = np.array([r["count_later_moving"] for r in tr], float)
    trf = np.array([r["count_later_fixed"] for r in tr], float)
    p(f"- (train, for more samples) re-centred {hits(trm, ytr)}/{len(ytr)}, fixed region {hits(trf, ytr)}/{len(ytr)}\n")
    p("| val file | SDC | count@10 | later frame | count re-centred | count fixed region |")
    p("|---|---|---|---|---|---|")
    for r in va:
        p(f"| {r['file']} | {'yes' if r['has_sdc'] else 'focus'} | {r['count']} | {r['later_frame']} | "
          f"{r['count_later_moving']} | {r['count_later_fixed']} |")
    text = "\n".join(L) + "\n"
    with open(os.path.join(OUT, "results.md"), "w") as fh:
        fh.write(text)
    sys.stdout.write(text)


if __name__ == "__main__":
    main()

import json, sys
import numpy as np
recs = json.load(open(sys.argv[1]))
methods = list(dict.fromkeys(r["method"] for r in recs))
levels = list(dict.fromkeys(r["level"] for r in recs))
cats = list(dict.fromkeys(r["cat"] for r in recs))
def agg(sel, key):
    v = [p[key] for r in sel if r["ok"] for p in r["parts"]]
    return np.mean(v) if v else np.nan
for lv in levels:
    print(f"\n## {lv}: all parts mean")
    print("| method | rot | trans | centroid trans | |scale err| | signed scale err |")
    for m in methods:
        sel = [r for r in recs if r["method"] == m and r["level"] == lv]
        if not sel: continue
        print(f"| {m} | {agg(sel,'rot'):.2f} | {agg(sel,'trans'):.4f} | {agg(sel,'centroid_trans'):.4f} | {agg(sel,'scale_rel'):.4f} | {agg(sel,'signed_scale'):+.4f} |")
    print(f"\n## {lv}: per category, translation per part (rot per part)")
    for c in cats:
        for m in methods:
            sel = [r for r in recs if r["method"] == m and r["level"] == lv and r["cat"] == c and r["ok"]]
            if not sel: continue
            n = len(sel[0]["parts"])
            tr = [np.mean([r["parts"][j]["trans"] for r in sel]) for j in range(n)]
            ro = [np.mean([r["parts"][j]["rot"] for r in sel]) for j in range(n)]
            ce = [np.mean([r["parts"][j]["centroid_trans"] for r in sel]) for j in range(n)]
            ss = [np.mean([r["parts"][j]["signed_scale"] for r in sel]) for j in range(n)]
            print(f"| {c} | {m} | " + ", ".join(f"{x:.4f}" for x in tr) + " | " + ", ".join(f"{x:.4f}" for x in ce)
                  + " | " + ", ".join(f"{x:.2f}" for x in ro) + " | " + ", ".join(f"{x:+.4f}" for x in ss) + " |")

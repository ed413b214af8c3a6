"""Measure Find Me on an evaluation split and write the results tables (docs/RESULTS.md).

    python tools/results.py ../shared/data/findme-eval [--out docs/RESULTS.md]

Runs in one go: ``findme eval`` with our method (and, for pairs, our estimator and the
paper's estimator on the same features and hypotheses), ``findme eval --method paper``
(the paper's hypotheses and estimator end to end), ``--no-gravity``, ``--room-spots auto``,
four runs with a phone's gravity (the dataset's refined by the photo's lines, and with a
simulated sensor error of ``PHONE_NOISE_DEG`` taken as it is or refined), and the split's own
scorer (``<split>/../../eval/score.py``) on each; then writes markdown tables, our method
next to the paper's, with the goals of the issues beside them.
"""

from __future__ import annotations

import argparse
import datetime as dt
import importlib.util
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import coverage_plot  # noqa: E402
import openings_report  # noqa: E402
import results_trust  # noqa: E402
import sigma_coverage  # noqa: E402

SINGLE = ["zind-level", "zind-tilted", "zind-pairs-tilted", "tum-cabinet", "zind-level-lowfloor",
          "zind-pairs-level"]
PAIRS = ["zind-pairs-level", "zind-pairs-tilted", "tum-cabinet-pairs", "kitti06-pairs"]


#: the simulated sensor error of a phone in the hand, degrees per axis
PHONE_NOISE_DEG = 1.5


def _score(split: Path, scorer: Path, pred: Path) -> dict:
    spec = importlib.util.spec_from_file_location("findme_eval_score", scorer)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.score(str(split), json.loads(pred.read_text()))["subsets"]


def _pct(d, key="median"):
    return "–" if not d or d.get(key) is None else f"{100 * d[key]:.2f} %"


def _pct_spread(d):
    """Median with the 90th percentile in brackets."""
    return "–" if not d or d.get("median") is None else \
        f"{100 * d['median']:.2f} % ({100 * d['p90']:.1f})"


def _rel(points: dict, kind: str) -> str:
    """Median relative 3D error of one point kind of a subset's ``points_3d``, with the share
    of its points answered when some are not (a point placed too loosely gets no answer)."""
    d = points.get(kind)
    if not d or not d.get("rel_err_pct_n"):
        return "–"
    cov = d.get("coverage")
    return f"{d['rel_err_pct_median']:.2f} %" + (f" (cov {cov:.2f})" if cov is not None
                                                 and cov < 0.995 else "")


def _single_rows(ours, paper):
    rows = ["| subset | views | answered ours / paper | top-1 ours (p90) | top-1 paper (p90) | "
            "best of 5 ours | best of 5 paper | oracle (any polyline) | floor 3D ours | "
            "floor 3D paper | wall 3D ours | wall 3D paper |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in SINGLE:
        o, p = ours[s].get("single_image"), paper[s].get("single_image")
        if not o:
            continue
        po, pp = ours[s].get("points_3d", {}), paper[s].get("points_3d", {})
        rows.append(f"| {s} | {o['n_views']} | {o['coverage']:.2f} / {p['coverage']:.2f} | "
                    f"{_pct_spread(o['pixel_error_top1'])} | "
                    f"{_pct_spread(p['pixel_error_top1'])} | {_pct(o['pixel_error_best_of_5'])} | "
                    f"{_pct(p['pixel_error_best_of_5'])} | {_pct(o['oracle_polyline_pixel_error'], 'mean')} | "
                    f"{_rel(po, 'floor')} | {_rel(pp, 'floor')} | {_rel(po, 'wall')} | {_rel(pp, 'wall')} |")
    return rows


def _pair_rows(results):
    rows = ["| subset | pairs | estimator | answered | translation median (p90) | yaw median (p90) |"
            " success |", "|---|---|---|---|---|---|---|"]
    for s in PAIRS:
        for name, res in results:
            for key in ("pairs", "pairs_clean_only"):
                p = res[s].get(key)
                if not p or not p["trans_err_m"].get("n"):
                    continue
                label = s + (" (clean)" if key == "pairs_clean_only" else "")
                rows.append(f"| {label} | {p['n_pairs']} | {name} | {p['coverage']:.2f} | "
                            f"{p['trans_err_m']['median']:.3f} m ({p['trans_err_m']['p90']:.2f}) | "
                            f"{p['yaw_err_deg']['median']:.2f}° ({p['yaw_err_deg']['p90']:.1f}) | "
                            f"{p['success_rate']:.2f} |")
    return rows


def _withheld_rows(with_g, without_g):
    rows = ["| subset | views | top-1 with / without gravity (p90) | floor 3D with / without | "
            "wall 3D with / without |", "|---|---|---|---|---|"]
    for s in SINGLE:
        o, w = with_g[s].get("single_image"), without_g[s].get("single_image")
        if not o or not w:
            continue
        pg, pw = with_g[s].get("points_3d", {}), without_g[s].get("points_3d", {})
        rows.append(f"| {s} | {o['n_views']} | {_pct_spread(o['pixel_error_top1'])} / "
                    f"{_pct_spread(w['pixel_error_top1'])} | {_rel(pg, 'floor')} / "
                    f"{_rel(pw, 'floor')} | {_rel(pg, 'wall')} / {_rel(pw, 'wall')} |")
    return rows


def _phone_rows(runs):
    """Floor and wall 3D medians of the single views, one column per (name, scored) run."""
    rows = ["| subset | views | " + " | ".join(f"{n}: floor / wall 3D" for n, _ in runs) + " |",
            "|---|---|" + "---|" * len(runs)]
    for s in SINGLE:
        o = runs[0][1][s].get("single_image")
        if not o:
            continue
        cells = [f"{_rel(r[s].get('points_3d', {}), 'floor')} / "
                 f"{_rel(r[s].get('points_3d', {}), 'wall')}" for _, r in runs]
        rows.append(f"| {s} | {o['n_views']} | " + " | ".join(cells) + " |")
    return rows


def _room_rows(results):
    rows = ["| subset | rooms | run | IoU median (p10) | wall length error | walls ok | "
            "corner error | localised | translation median (p90) | yaw median (p90) | success |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, res in results:
        for s, sub in sorted(res.items()):
            r = sub.get("rooms")
            if not r:
                continue
            t, y = r["loc_trans_err_m_pooled"], r["loc_yaw_err_deg_pooled"]
            rows.append(
                f"| {s} | {r['n_rooms']} | {name} | {r['iou']['median']:.3f} ({r['iou']['p10']:.3f}) | "
                f"{100 * r['wall_len_rel_err']['median']:.1f} % | {r['wall_frac_ok']['median']:.2f} | "
                f"{r['corner_err_m']['median']:.3f} m | {r['loc_coverage']:.2f} | "
                f"{t['median']:.3f} m ({t['p90']:.2f}) | {y['median']:.2f}° ({y['p90']:.1f}) | "
                f"{r['loc_success_rate']:.3f} |")
    return rows


def _room_answer_rows(runs) -> list[str]:
    """Per room: each run's plan IoU, or its refusal with the reason (``runs``: (name,
    scored results, predictions)). A room with IoU < 0.5 published is a wrong room."""
    out = ["| room | " + " | ".join(name for name, _, _ in runs) + " |",
           "|---|" + "---|" * len(runs)]
    per = [(res.get("zind-rooms", {}).get("rooms") or {}).get("per_room", {})
           for _, res, _ in runs]
    for rid in sorted(set().union(*per)):
        cells = []
        for (_, _, preds), p in zip(runs, per):
            why = (preds.get("rooms_refused") or {}).get(rid)
            kept = len(((preds.get("rooms") or {}).get(rid) or {}).get("poses") or {})
            if why:
                cells.append(f"refused: {why}" + (f" (outline only: {kept} photos' poses kept)"
                                                   if kept else ""))
            elif rid in p and not p[rid].get("predicted_polygon", True):
                cells.append("no plan")
            elif rid in p:
                iou = p[rid]["iou"]
                cells.append(f"IoU {iou:.2f}" + (" (**wrong room published**)" if iou < 0.5 else ""))
            else:
                cells.append("–")
        out.append(f"| {rid} | " + " | ".join(cells) + " |")
    return out


def _opening_rows(split, runs) -> list[str]:
    """Doors and openings said (``tools/openings_report.py``) per run, pooled over the rooms."""
    out = ["| run | said | on a true door or opening (share) | true doors and openings | "
           "of them said |", "|---|---|---|---|---|"]
    for name, preds in runs:
        s = [sum(v) for v in zip(*(r for _, r in openings_report.prediction_rows(split, preds)))]
        if s:
            out.append(f"| {name} | {s[0]:.2f} m | {s[1]:.2f} m ({s[1] / max(s[0], 1e-9):.2f}) | "
                       f"{s[2]:.2f} m | {s[3]:.2f} m |")
    return out


def _locate_rows(rows) -> list[str]:
    """"Find me" rows from ``tools/locate_report.py --json``: per room and pooled, each way."""
    out = ["| room | photos | from | localised | a right pose among the candidates | "
           "translation median | yaw median | stated: right / wrong | candidates given: the "
           "right one among them |", "|---|---|---|---|---|---|---|---|---|"]
    rooms = sorted({r["room"] for r in rows})
    for name in rooms + ["all"]:
        rr = [r for r in rows if name in ("all", r["room"])]
        for how in ("walls", "photos", "turn walls", "turn photos"):
            done = [r[how] for r in rr if how in r and "error" not in r[how]]
            med = (lambda k, f: format(statistics.median(d[k] for d in done), f) if done else "–")
            out.append(f"| {name} | {len(rr)} | {how} | "
                       f"{sum(d['ok'] for d in done) / max(len(rr), 1):.2f} | "
                       f"{sum(d['any_ok'] for d in done)} | {med('t_m', '.3f')} m | "
                       f"{med('yaw_deg', '.2f')}° | "
                       f"{sum(d['ok'] for d in done if d['found'])} / "
                       f"{sum(not d['ok'] for d in done if d['found'])} | "
                       f"{sum(not d['found'] for d in done)}: "
                       f"{sum(d['any_ok'] for d in done if not d['found'])} |")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("split", type=Path)
    ap.add_argument("--scorer", type=Path)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "RESULTS.md")
    a = ap.parse_args(argv)
    scorer = a.scorer or a.split.resolve().parents[1] / "eval" / "score.py"
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        run = [sys.executable, "-m", "findme.cli", "eval", str(a.split)]
        subprocess.run(run + ["--out", str(t / "ours.json"), "--motion-method",
                              "findme,features,paper"], check=True)
        subprocess.run(run + ["--out", str(t / "paper.json"), "--method", "paper",
                              "--motion-method", "paper"], check=True)
        subprocess.run(run + ["--out", str(t / "nograv.json"), "--no-gravity"], check=True)
        subprocess.run(run + ["--out", str(t / "auto.json"), "--room-spots", "auto"], check=True)
        phone = {"refined": ["--gravity-refine"],
                 "noisy": ["--gravity-noise", str(PHONE_NOISE_DEG)],
                 "noisy_refined": ["--gravity-noise", str(PHONE_NOISE_DEG), "--gravity-refine"],
                 "noisy_refined_declared": ["--gravity-noise", str(PHONE_NOISE_DEG),
                                            "--gravity-refine", "--gravity-sigma",
                                            str(PHONE_NOISE_DEG)]}
        said = ["--gravity-noise", str(PHONE_NOISE_DEG), "--gravity-refine", "--gravity-sigma",
                str(PHONE_NOISE_DEG), "--declared-surface"]
        subprocess.run(run + ["--out", str(t / "said.json")] + said, check=True)
        for name, flags in phone.items():
            subprocess.run(run + ["--out", str(t / f"{name}.json")] + flags, check=True)
        subprocess.run([sys.executable, str(Path(__file__).with_name("locate_report.py")),
                        str(a.split), "--json", str(t / "locate.json")], check=True,
                       stdout=subprocess.DEVNULL)
        locate = json.loads((t / "locate.json").read_text())
        trust_tools = results_trust.run(a.split, t)
        loro = _score(a.split, scorer, trust_tools["loro"])
        refit = _score(a.split, scorer, trust_tools["refit"])
        ours_preds = json.loads((t / "ours.json").read_text())
        nograv_preds = json.loads((t / "nograv.json").read_text())
        phone_preds = json.loads((t / "noisy_refined_declared.json").read_text())
        said_preds = json.loads((t / "said.json").read_text())
        # the coverage tables as pictures, beside the markdown (``coverage_plot``)
        figures = {"given": "coverage.svg", "phone": "coverage-phone.svg"}
        a.out.parent.mkdir(parents=True, exist_ok=True)
        for key, preds, what in (("given", ours_preds, "the dataset's gravity"),
                                 ("phone", phone_preds, f"a phone's ({PHONE_NOISE_DEG:g}°)")):
            (a.out.parent / figures[key]).write_text(coverage_plot.svg(
                sigma_coverage.collect(str(a.split), preds),
                f"Do the stated 1-sigmas hold? Gravity: {what}"))
        ours = _score(a.split, scorer, t / "ours.json")
        nograv = _score(a.split, scorer, t / "nograv.json")
        auto_spots = _score(a.split, scorer, t / "auto.json")
        paper = _score(a.split, scorer, t / "paper.json")
        phone = {name: _score(a.split, scorer, t / f"{name}.json") for name in phone}
        ours_paper_est = _score(a.split, scorer, t / "ours.paper.json")
        ours_features = _score(a.split, scorer, t / "ours.features.json")
    split = json.loads((a.split / "index.json").read_text()).get("split", "?")
    lines = [
        "# Results", "",
        f"Measured {dt.date.today().isoformat()} on the **{split}** split of findme-eval with its own "
        "scorer, by `python tools/results.py ../shared/data/findme-eval`. Medians; ours next to "
        "the paper's method in the same run.", "",
        "## Single image: floor pixel error and 3D points", "",
        "Goals: best of 5 <= 4 %, top-1 <= 8 % (tum-cabinet: 8 % / 12 %); floor points <= 1.5 %, "
        "ZInD wall points under the top hypothesis <= 4 %. \"paper\" = `--method paper` "
        "(Hough, level camera, slope groups, Canny edge support). \"answered\": views with at "
        "least one hypothesis; a photo with no straight line at all gets an empty list with the "
        "reason, which the scorer counts as pixel error 1.0 even where no floor is visible. "
        "\"cov\": the share of the 3D points answered, where some are not (a point whose "
        "1-sigma exceeds half its distance gets no answer, with the reason).", "",
        *_single_rows(ours, paper), "",
        "## Two images: planar motion", "",
        "Goals: translation <= 0.05 m and yaw <= 1° (1.5° on ZInD pairs) with >= 95 % answered. "
        "\"ours\": our hypotheses and estimator (the photos' layouts registered with the "
        "feature matches); \"features only\": the same matches without the layouts (the "
        "default before them); \"paper estimator\": our hypotheses and features with the "
        "paper's estimator (eqs. 5-8); \"paper end to end\": the paper's hypotheses and "
        "estimator.", "",
        *_pair_rows([("ours", ours), ("features only", ours_features),
                     ("paper estimator", ours_paper_est), ("paper end to end", paper)]), "",
        "## Photos without the phone's gravity", "",
        "`findme eval --no-gravity`: every view's gravity withheld, as for a photo without "
        "sensors; gravity comes from the image's vanishing directions (else level is assumed).",
        "", *_withheld_rows(ours, nograv), "",
        *_pair_rows([("ours, gravity withheld", nograv)]), "",
"## A phone's gravity: sensor error, refined by the photo's lines", "",
        "A phone's gravity is not exact: held still its accelerometer is good to ~0.5°, in the "
        "hand to 1-3°. The services combine a given gravity with the photo's own vertical and "
        "horizontal lines near it (`gravity_fusion`: the vanishing directions searched within "
        "4 sigma (at least 6°) of the sensor's tilt, then the two Gaussian measurements "
        "combined; again after the boundary is known), unless its sigma is 0. The dataset's "
        "gravity is exact, so the tables above take it as it is (`findme eval`); here "
        f"`--gravity-noise {PHONE_NOISE_DEG:g}` tilts every view's gravity by a seeded random "
        f"N(0, {PHONE_NOISE_DEG:g}°) in pitch and in roll, as a phone in the hand would send it. "
        "\"exact\": the dataset's gravity as it is (the tables above); \"exact, refined\": "
        "combined with the lines at the default 1-sigma of 0.5° (what the services do with it); "
        "\"noisy\": the noisy gravity taken as it is; \"noisy, refined\": combined at the "
        f"default 0.5°; \"noisy, refined at {PHONE_NOISE_DEG:g}°\": declared with its true "
        "1-sigma (`--gravity-sigma`).", "",
        *_phone_rows([("exact", ours), ("exact, refined", phone["refined"]),
                      ("noisy", phone["noisy"]), ("noisy, refined", phone["noisy_refined"]),
                      (f"noisy, refined at {PHONE_NOISE_DEG:g}°",
                       phone["noisy_refined_declared"])]), "",
        *_pair_rows([("ours, exact, refined", phone["refined"]),
                     ("ours, noisy", phone["noisy"]),
                     ("ours, noisy, refined", phone["noisy_refined"]),
                     (f"ours, noisy, refined at {PHONE_NOISE_DEG:g}°",
                      phone["noisy_refined_declared"])]), "",
        "## Rooms: floor plan and \"find me\" on it", "",
        "`findme eval` builds each room's floor plan from its photos (`findme plan`) and places "
        "every photo on it. \"spots by id\": which photos were taken from one spot comes from the "
        "view ids' `_p<N>_` token, as a capture app's \"new spot\" button would mark it "
        "(`--room-spots ids`, the default); \"spots found\": from the photos alone "
        "(`--room-spots auto`). Goal: localisation success (<= 0.25 m and <= 5°) >= 0.90.", "",
        *_room_rows([("spots by id", ours), ("spots found", auto_spots),
                     ("gravity withheld", nograv)]), "",
        "Each room's plan, or why it was refused (\"gravity withheld\": `--no-gravity`, "
        "the photos agree on gravity spot by spot; a refused outline counts as IoU 0 and its "
        "walls as failures above, while its photos' poses, kept with their 1-sigmas, are "
        "scored as placed):", "",
        *_room_answer_rows([("spots by id", ours, ours_preds),
                            ("gravity withheld", nograv, nograv_preds)]), "",
        "Doors and openings (`tools/openings_report.py`): a stretch of wall is said open where "
        "at least as many photos saw the floor go on past it as saw its base standing there "
        "(`apertures`); said metres within 0.1 m of one of the dataset's doors or openings are "
        "on a true one. A closed door shows no floor beyond, so not every door can be said. "
        "The tool's `--rendered` run counts the openings said in closed rendered rooms (every "
        "one wrong).", "",
        *_opening_rows(a.split, [("dataset's gravity", ours_preds),
                                 (f"phone's gravity ({PHONE_NOISE_DEG:g}°)", phone_preds),
                                 ("gravity withheld", nograv_preds)]), "",
        "\"Find me\" on a plan (`tools/locate_report.py`): each spot's photos left out of their "
        "room's plan and found, one by one, on the plan of the other spots, as new photos from "
        "a new place: \"walls\" from the plan's walls alone (`findme locate-in PLAN.json "
        "PHOTO`), \"photos\" with the plan's photos too (`--photos`: the new photo's feature "
        "matches and motions with them); \"turn\": the spot's photos found together (`findme "
        "locate-in PLAN.json PHOTO...`: a user turning round at the new place). Localised: "
        "within 0.25 m and 5°. \"stated\": `locate-in` says \"you are at\" (only a turn with "
        "the plan's photos and a clear best: `relocalise.verdict`); otherwise it says it cannot "
        "tell and gives its candidates, best first.", "",
        *_locate_rows(locate), "",
        *results_trust.section(a.split, ours, refit, loro, ours_preds, nograv_preds,
                               phone_preds, trust_tools, PHONE_NOISE_DEG, said_preds,
                               figures),
    ]
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text("\n".join(lines) + "\n")
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()

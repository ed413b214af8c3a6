"""The same answers on every machine, on real photos: a sample of dev views and pairs (those
whose answers once hinged on the BLAS kernel, with the views' gravity as given and as the
services refine a phone's) predicted under each OpenBLAS kernel and with numpy's AVX-512
dispatch off (``tests.numeric_envs``), and compared beyond ``findme regress``'s tolerances
(``tools/kernel_sameness.py`` does the whole split). Skips without ../shared."""

from __future__ import annotations

import importlib.util
import json

import pytest

from tests.conftest import EVAL_DIR, needs_eval_data
from tests.numeric_envs import ROOT, env_params, run_python

#: views and pairs whose answers differed between Haswell and SkylakeX before the ties
VIEWS = ("tum_cab_0002", "zr_r10_p16_v3", "zt_r07_p19_v0", "zl_r17_p7_v01")
REFINED = ("zt_r01_p14_v1", "zr_r06_p10_v7")     # gravity refined by the photo's lines
PAIRS = ("tum_cab_0002_0003", "zpt_r17_p7_p8_t1")

_SCRIPT = """
import json
from findme.evaluation.views import GravityInput, predict_view
from findme.evaluation.pairs import predict_pair
d = {data!r}
views = {{v: predict_view((d + "/views", v, "findme", 10, True))[1] for v in {views!r}}}
views.update({{v + "/refined": predict_view((d + "/views", v, "findme", 10,
                                             GravityInput(refine=True)))[1]
               for v in {refined!r}}})
pairs = {{p: predict_pair((d + "/pairs", d + "/views", p, "findme", ["findme"], True))[1]
          .get("findme") for p in {pairs!r}}}
print(json.dumps({{"views": views, "pairs": {{k: v for k, v in pairs.items() if v}}}}))
"""


def _sameness():
    spec = importlib.util.spec_from_file_location("kernel_sameness",
                                                  ROOT / "tools" / "kernel_sameness.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def reference():
    needs_eval_data()
    r = run_python(_SCRIPT.format(data=str(EVAL_DIR), views=VIEWS, refined=REFINED,
                                  pairs=PAIRS), {"OPENBLAS_CORETYPE": "Haswell"})
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.splitlines()[-1])


@pytest.mark.parametrize("env", env_params())
def test_dev_sample_answers_the_same_under(env, reference):
    r = run_python(_SCRIPT.format(data=str(EVAL_DIR), views=VIEWS, refined=REFINED,
                                  pairs=PAIRS), env)
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads(r.stdout.splitlines()[-1])
    ks = _sameness()
    assert len(reference["views"]) == len(VIEWS) + len(REFINED)
    assert len(reference["pairs"]) == len(PAIRS)
    views = ks.compare_views(reference["views"], got["views"], 1.0)
    assert views == {k: [] for k in views}, views
    assert ks.compare_pairs(reference["pairs"], got["pairs"]) == []

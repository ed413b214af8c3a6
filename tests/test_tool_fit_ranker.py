"""``tools/fit_ranker.py``'s fit gives the same weights under every numeric environment
(``tests.numeric_envs``): its softmax at temperature 0.01 over hundreds of Adam steps turns a
last-bit difference in one product into other weights (the dev split's refit, 2026-12-01:
``far`` -16 under the Haswell kernel, -32 under SkylakeX, from the same candidates), and the
leave-one-room-out figures in docs/RESULTS.md come from it. Candidates rendered here: random
features whose errors a hidden weight vector explains."""

from __future__ import annotations

import pytest

from tests.numeric_envs import env_params, run_python

_SCRIPT = """
import sys
import numpy as np
sys.path.insert(0, "tools")
import fit_ranker as fr
rng = np.random.default_rng(7)
K = len(fr.FEATURES)
truth = rng.normal(size=K)
data = []
for _ in range(60):
    f = rng.normal(size=(25, K))
    s = np.sum(f * truth, axis=1)
    data.append((f, np.clip((s.max() - s) / 40.0, 0.0, 0.3)))
free = np.ones(K, bool)
free[0] = False
w = fr.fit(data, np.full(K, 0.1), free, iters=300)
w = fr.grid_choice(data, w, "far", fr.FAR_GRID)
print(w.tobytes().hex())
print(float(np.mean(fr.top1(data, w))), float(np.mean(fr.top1(data, np.full(K, 0.1)))))
"""


@pytest.fixture(scope="module")
def reference():
    out = run_python(_SCRIPT, {})
    assert out.returncode == 0, out.stderr
    return out.stdout.split()


@pytest.mark.parametrize("env", env_params())
def test_the_fit_gives_the_same_weights_bit_for_bit(reference, env):
    out = run_python(_SCRIPT, env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[0] == reference[0]


def test_the_fit_lowers_the_top1_error(reference):
    fitted, start = float(reference[1]), float(reference[2])
    assert fitted < 0.5 * start

"""Every JSON file and object that jaxmpm writes is standard JSON: a value that is not finite (the
error of a run that broke down) is ``null``, never the ``NaN`` or ``Infinity`` that other readers
refuse."""

import json
import math

import jax.numpy as jnp
import numpy as np

from jaxmpm._json import dumps


def refuse(token):
    raise AssertionError(f"non-standard JSON token {token}")


def test_values_that_are_not_finite_are_null():
    obj = dict(
        nan=float("nan"),
        inf=np.float64("inf"),
        f32=np.float32("-inf"),
        array=jnp.asarray([1.5, jnp.nan]),
        scalar=jnp.asarray(2.0),
        nested=[(1, None, "s", True), {"x": math.nan}],
    )
    back = json.loads(dumps(obj, indent=1), parse_constant=refuse)
    assert back == dict(
        nan=None,
        inf=None,
        f32=None,
        array=[1.5, None],
        scalar=2.0,
        nested=[[1, None, "s", True], {"x": None}],
    )


def test_a_study_writes_null_for_the_errors_of_a_run_that_broke_down(tmp_path):
    from jaxmpm.studies import convergence

    rows = [dict(case="sod", method="spq", cells=16, x_rms=float("nan"), status="x at step 3")]
    orders = [dict(case="sod", method="spq", order=np.float64("nan"))]
    convergence._write_shocks(tmp_path, "table\n", rows, orders, {"sod": float("inf")})
    saved = json.loads((tmp_path / "shocks.json").read_text(), parse_constant=refuse)
    assert saved["runs"][0]["x_rms"] is None and saved["orders"][0]["order"] is None
    assert saved["energy"] == {"sod": None}

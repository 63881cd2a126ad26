"""Special values met late in a run: does a compiled block answer, to the bit, as Python and
python-control do?

    python benchmarks/special_values.py                 # every call below, about 5 min
    python benchmarks/special_values.py "np.sign(v)"    # the calls given

Each call ``f(v)`` becomes a one-state discrete block ``x[k+1] = f(u[k])`` whose input is 1.0
at every step but step 300, where it is a special value: a zero of either sign, a halfway
number, a subnormal, a float near the ends of float64 or beyond 64-bit integers. Step 300
is past the first piece, which the engine runs both ways and compares: a difference there
would be silent. For every call the script prints the engine's mode and the values at
which the compiled run (``compile=True``) differs from controlkit's Python run
(``compile=False``), and at which that differs from ``control.input_output_response``;
bits compared, so ``0.0`` and ``-0.0`` differ. The functions are written to a temporary
folder, since the engine reads a function's source.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
import tempfile
import warnings
from pathlib import Path

import control as ct
import numpy as np

import controlkit

SPECIAL = [0.0, -0.0, -1.0, -2.5, 2.5, 1.5, -1.5, 0.5, -0.5, 5e-324, -5e-324, 1e308, -1e308,
           1e19, -1e19, 2.0, -2.0, 3.0, -3.0, 1e-300, 0.25, -7.0]
CALLS = """np.sign(v); np.abs(v); abs(v); np.fabs(v); np.floor(v); np.ceil(v); np.trunc(v);
np.rint(v); np.round(v); np.round(v, 2); round(v, 2); round(v); np.sqrt(v); math.sqrt(v);
np.square(v); np.sin(v); np.cos(v); math.sin(v); math.exp(v); math.log(v); math.atan(v);
math.tanh(v); np.deg2rad(v); np.sinc(v); -v; np.reciprocal(v); 1.0 / v;
math.copysign(1.0, v); np.copysign(1.0, v); np.spacing(v); np.nan_to_num(v); int(v);
math.floor(v); math.ceil(v); math.trunc(v); v // 1.0; v % 1.0; v % -2.0; v // -2.0;
np.mod(v, -2.0); np.mod(v, 2.0); np.remainder(v, 3.0); np.fmod(v, -2.0);
math.fmod(v, -2.0); np.floor_divide(v, -2.0); divmod(v, -2.0)[1]; np.divmod(v, -2.0)[1];
np.maximum(v, 0.0); np.minimum(v, 0.0); np.maximum(0.0, v); np.minimum(-0.0, v);
max(v, 0.0); min(v, 0.0); np.fmax(v, 0.0); np.clip(v, 0.0, 1.0); np.clip(v, -1.0, 0.0);
np.arctan2(v, -1.0); math.atan2(v, -1.0); v ** 2; math.pow(v, 3);
np.sign(v * 1e300 * 1e10); np.interp(v, [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0]);
np.prod(np.array([v, -1.0])); np.linalg.norm(np.array([v, 0.0]));
np.sum(np.array([v, -0.0])); np.max(np.array([v, -0.0])); np.min(np.array([0.0, v]));
np.cross(np.array([v, 0.0, 1.0]), np.array([0.0, 1.0, 0.0]))[2];
np.sort(np.array([v, -0.0, 0.0]))[1]; np.sign(np.array([v, -v]))[1];
np.maximum(np.array([v, 1.0]), 0.0)[0]; v * 0.0""".replace("\n", " ").split("; ")
STEPS, LATE = 400, 300


def _bits(value) -> str:
    """A float's bits as text (every NaN alike)."""
    value = float(value)
    return "nan" if value != value else value.hex()


def _outcome(run, block, T, U, **options):
    """What a run gives at the step after the special value: its bits and mode, or the
    error's type."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            resp = run(block, T, U, X0=[0.0], **options)
        except Exception as error:  # noqa: BLE001 - the error's type is the outcome
            return type(error).__name__, "-"
    return _bits(np.asarray(resp.outputs).reshape(-1)[LATE + 1]), getattr(
        resp, "engine_mode", "-")


def _block(call: str, folder: Path):
    """The discrete block ``x[k+1] = call(u[k])``, its function read from a file."""
    tag = hashlib.sha1(call.encode()).hexdigest()[:12]
    path = folder / f"special_{tag}.py"
    path.write_text("import math\n\nimport numpy as np\n\n\ndef update(t, x, u, params):\n"
                    f"    v = u[0]\n    return [float({call})]\n")
    spec = importlib.util.spec_from_file_location(f"special_{tag}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return ct.nlsys(module.update, lambda t, x, u, params: x, inputs=1, outputs=1,
                    states=1, dt=1, name="special")


def main(calls) -> int:
    T = np.arange(float(STEPS))
    silent = 0
    with tempfile.TemporaryDirectory() as folder:
        for call in calls:
            block = _block(call, Path(folder))
            compiled_differs, python_differs, mode = [], [], "-"
            for value in SPECIAL:
                U = np.ones(STEPS)
                U[LATE] = value
                theirs = _outcome(ct.input_output_response, block, T, U)
                python = _outcome(controlkit.input_output_response, block, T, U,
                                  compile=False)
                compiled = _outcome(controlkit.input_output_response, block, T, U,
                                    compile=True)
                mode = compiled[1]
                if compiled[0] != python[0]:
                    compiled_differs.append(f"{value!r}: {python[0]} / {compiled[0]}")
                if python[0] != theirs[0]:
                    python_differs.append(f"{value!r}: {theirs[0]} / {python[0]}")
            silent += bool(compiled_differs or python_differs)
            print(f"{call:40s} {mode:14s} compiled differs: "
                  f"{'; '.join(compiled_differs) or 'no'}; python-control differs: "
                  f"{'; '.join(python_differs) or 'no'}", flush=True)
    print(f"{silent} of {len(calls)} calls differ somewhere")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:] or CALLS))

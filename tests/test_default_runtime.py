"""The defaults a user gets without calling tc.init: arch "auto" and f32, in a fresh process.

The test session itself runs in f64 (conftest.py), so the f32 path is checked here, in a
subprocess, against the same closed forms: bounce apex e^2 h and a block resting at e = 0.9.
"""

import json
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import json
    import numpy as np
    import tai_coll as tc
    from tai_coll import runtime

    assert runtime.info() is None          # importing starts nothing
    r, h, e = 0.01, 0.5, 0.5
    scene = tc.Scene(dt=1 / 3000, substeps=10)   # first use starts the default runtime
    scene.add_collider(tc.Plane(), material=tc.Material(restitution=e, friction=0.3))
    scene.add_particles(positions=[[0, h + r, 0], [1, r, 0]], radius=r)
    apex, bounced = 0.0, False
    for _ in range(150):
        scene.step()
        bounced |= scene.velocities()[0, 1] > 1e-3
        if bounced:
            apex = max(apex, scene.positions()[0, 1] - r)
    info = runtime.info()
    print(json.dumps(dict(arch=info.arch, requested=info.requested_arch, precision=info.precision,
                          dtype=str(scene.positions().dtype), apex=float(apex),
                          rest_speed=float(np.abs(scene.velocities()[1]).max()),
                          rest_height=float(scene.positions()[1, 1]))))
""")


def test_auto_arch_and_f32_defaults():
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["requested"] == "auto" and result["precision"] == "f32"
    assert result["dtype"] == "float32"
    assert result["arch"] in ("cpu", "cuda", "metal")
    assert abs(result["apex"] - 0.25 * 0.5) < 0.03 * 0.5 * 0.25 + 2e-3
    assert result["rest_speed"] < 1e-5
    assert abs(result["rest_height"] - 0.01) < 1e-5

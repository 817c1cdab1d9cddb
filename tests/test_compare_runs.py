"""tools/compare_runs.py: two runs' renders matched by job name, tables cell by cell."""
import os

import numpy as np

from experiments.lib.jobs import Job, JobResult
from experiments.lib.store import JobStore
from tools import compare_runs


def _run(out, image, seconds: str, error: str) -> str:
    store = JobStore(os.path.join(out, "store"))
    job = Job(key=f"study/cell/r1-{abs(hash(str(out))) % 10**12:012d}", scene="s.xml",
              scene_sha256="0", method="m", width=2, height=1, spp=4, seed=1)
    store.put(job, JobResult(image, None, 4, 1, wall_seconds=1.0, kernel_seconds=0.5))
    os.makedirs(os.path.join(out, "study"), exist_ok=True)
    with open(os.path.join(out, "study", "table.csv"), "w") as f:
        f.write(f"method,relMSE,seconds\nm,{error},{seconds}\n")
    return str(out)


def test_same_numbers_pass_and_a_changed_image_or_cell_is_caught(tmp_path, capsys):
    image = np.full((1, 2, 3), 0.5, np.float32)
    old = _run(tmp_path / "old", image, "1.0", "0.25")
    same = _run(tmp_path / "same", image, "2.0", "0.25")          # only the clock moved
    assert compare_runs.main([old, same, "--ignore", "seconds"]) == 0
    assert "1 bit-identical, 0 different" in capsys.readouterr().out
    # negative controls: the clock column unignored; one ulp in one pixel; another error
    assert compare_runs.main([old, same]) == 1
    nudged = image.copy()
    nudged[0, 1, 2] = np.nextafter(np.float32(0.5), np.float32(1))
    assert compare_runs.main([old, _run(tmp_path / "ulp", nudged, "1.0", "0.25")]) == 1
    assert "different image: study/cell/r1" in capsys.readouterr().out
    assert compare_runs.main([old, _run(tmp_path / "cell", image, "1.0", "0.26"),
                              "--ignore", "seconds"]) == 1
    assert "column 'relMSE': 0.25 != 0.26" in capsys.readouterr().out

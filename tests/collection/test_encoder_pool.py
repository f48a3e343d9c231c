"""A route process's encoder pool never keeps that process from exiting."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

SCRIPT = textwrap.dedent("""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from b2d_data.collection.job import encoder_pool


    def use_encoders() -> int:
        return encoder_pool(1).submit(abs, -3).result()


    if __name__ == "__main__":
        method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
        with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context(method)) as routes:
            print(routes.submit(use_encoders).result())
""")


def test_a_pool_worker_with_encoders_exits_when_its_pool_shuts_down(tmp_path: Path) -> None:
    # Before the fix the route worker's exit joined its encoder processes, which only stop with their owner: the
    # outer pool's shutdown never returned.
    script = tmp_path / "nested_pools.py"
    script.write_text(SCRIPT)
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "3"

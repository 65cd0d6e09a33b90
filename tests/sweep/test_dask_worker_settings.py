"""The settings every Dask worker of a sweep gets, as environment variables a cluster reads."""

from __future__ import annotations

import re
from pathlib import Path

from somo_sweep.sweep.run.execution import DASK_WORKER_CONFIG, dask_environment


def test_the_worker_settings_read_as_the_environment_dask_reads() -> None:
    import dask

    env = dask_environment()
    assert env["DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL"] == "1s"
    assert env["DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED"] == "False"
    assert env["DASK_DISTRIBUTED__ADMIN__SYSTEM_MONITOR__INTERVAL"] == "2s"
    # Dask's own reader turns these variables back into the same settings.
    parsed = dask.config.collect_env(env)
    for key, value in DASK_WORKER_CONFIG.items():
        node: object = parsed
        for part in key.split("."):
            assert isinstance(node, dict)
            node = node.get(part, node.get(part.replace("-", "_")))
        assert node == value, key


def test_the_cluster_page_gives_exactly_these_settings_to_a_cluster() -> None:
    page = (Path(__file__).resolve().parents[2] / "docs" / "cluster.md").read_text()
    given = dict(re.findall(r"(DASK_[A-Z_]+)=(\S+)", page))
    assert given == dask_environment()

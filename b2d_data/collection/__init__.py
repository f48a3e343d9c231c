"""Collection: the data agent, one-route jobs and the ``b2d-collect`` loop (route runner + expert + clip writer).

``collect(CollectConfig(out=..., scenarios=("Accident",), n=50))`` runs a collection; ``run_route_job`` runs one
route into one clip; ``DataAgent`` turns a recorded tick into a ``FrameRecord``.
"""

from b2d_data.collection.data_agent import DataAgent
from b2d_data.collection.job import CollectConfig, JobResult, run_route_job
from b2d_data.collection.plan import CollectError, CollectionPlan, RouteTask, plan_collection, route_seed
from b2d_data.collection.runner import CollectSummary, Progress, ScenarioSummary, collect, summary_table
from b2d_data.collection.towns import TownError, TownSource

__all__ = [
    "CollectConfig", "CollectError", "CollectSummary", "CollectionPlan", "DataAgent", "JobResult", "Progress",
    "RouteTask", "ScenarioSummary", "TownError", "TownSource", "collect", "plan_collection", "route_seed",
    "run_route_job", "summary_table",
]  # fmt: skip

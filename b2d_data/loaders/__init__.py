"""PyTorch loading of Bench2Drive corpora: ``ClipDataset``, its ``collate``, the parquet corpus index, HD maps."""

from b2d_data.loaders.collate import Batch, collate
from b2d_data.loaders.dataset import BadFrame, ClipDataset, worker_init_fn
from b2d_data.loaders.hdmap import MAP_TYPES, HDMap
from b2d_data.loaders.index import BuildReport, CorpusIndex, open_index
from b2d_data.loaders.sample import BOX_CLASSES, TRIGGER_TYPES, SampleOptions

__all__ = [
    "BOX_CLASSES", "MAP_TYPES", "TRIGGER_TYPES", "BadFrame", "Batch", "BuildReport", "ClipDataset", "CorpusIndex", "HDMap",
    "SampleOptions", "collate", "open_index", "worker_init_fn",
]  # fmt: skip

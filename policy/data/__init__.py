"""Datasets of (I, M, a) samples: synthesis, sharded storage, streaming reader."""

from .shards import Dataset, DatasetError, ShardWriter, open_dataset
from .synth import synthesize

__all__ = ["Dataset", "DatasetError", "ShardWriter", "open_dataset", "synthesize"]

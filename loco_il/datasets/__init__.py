from loco_il.datasets.create import create_dataset
from loco_il.datasets.trajectory import DatasetError, Trajectories

__all__ = ["Trajectories", "DatasetError", "create_dataset"]

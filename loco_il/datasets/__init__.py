from loco_il.datasets.trajectory import DatasetError, Trajectories

__all__ = ["Trajectories", "DatasetError"]

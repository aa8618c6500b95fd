"""One module per body family; importing this package registers every body."""
from loco_il.environments.bodies import classic  # noqa: F401

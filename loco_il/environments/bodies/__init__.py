"""One module per body family; importing this package registers every body."""
from loco_il.environments.bodies import classic  # noqa: F401
from loco_il.environments.bodies import menagerie  # noqa: F401
from loco_il.environments.bodies import myoleg  # noqa: F401
from loco_il.environments.bodies import locomujoco  # noqa: F401

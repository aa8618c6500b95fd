"""`from loco_il.algorithms import GAIL, ...` gives the registered agent classes."""
import pytest


def test_public_algorithm_names_are_the_registered_agents():
    import loco_il.algorithms as algorithms
    from loco_il.algorithms.common.agent_base import ILAgent
    from loco_il.algorithms.factory import import_all
    registered = set(import_all().values())
    agents = [getattr(algorithms, n) for n in ("GAIL", "VAIL", "GAIfO", "IQLearn", "LSIQ", "LSIQfO", "SQIL", "BC")]
    assert all(issubclass(a, ILAgent) for a in agents)
    assert set(agents) == registered
    with pytest.raises(AttributeError, match="no attribute 'Gail'"):
        algorithms.Gail

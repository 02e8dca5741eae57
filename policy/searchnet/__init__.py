"""searchnet: a learned search policy on the belief state, imitating the belief planner with
DAgger, then fine-tuned with PPO (the critic may see the truth, the actor never)."""

from .checkpoint import FORMAT, load_searchnet, read_searchnet, save_searchnet
from .config import SearchNetConfig
from .model import SearchNet
from .policy import SearchNetPolicy, load_searchnet_policy

__all__ = ["FORMAT", "SearchNet", "SearchNetConfig", "SearchNetPolicy", "load_searchnet",
           "load_searchnet_policy", "read_searchnet", "save_searchnet"]

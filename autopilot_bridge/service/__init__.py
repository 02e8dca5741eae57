"""The search service: the policy loop, flying the legs, the fence, the bring-down on every exit
path, the journal a restarted companion resumes from, and the search's data."""

from .policy_service import PolicyService, SearchLog, SearchSpec

__all__ = ["PolicyService", "SearchLog", "SearchSpec"]

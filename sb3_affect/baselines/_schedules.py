"""Plain-data schedules over episodes (kept for imports of earlier versions; they live in ``sb3_affect.settings``)."""

from sb3_affect.settings import DECAYS, check_positive_int, episode_decay

__all__ = ["DECAYS", "check_positive_int", "episode_decay"]

"""Loco-manipulation: a biped fetches an object with both palms (or a small one with one hand) and places it on
another table."""

from sim_bridge.fetch.goal import FetchGoal, FetchPlan, check_fetchable, check_place_on_a_table, for_one_hand, plan_fetch
from sim_bridge.fetch.grip import GripConfig
from sim_bridge.fetch.one_hand_fetch import OneHandFetch, fetch_skill
from sim_bridge.fetch.skill import FetchSkill
from sim_bridge.fetch.stance import Stance, StanceConfig, plan_stance

__all__ = [
    "FetchGoal", "FetchPlan", "FetchSkill", "GripConfig", "OneHandFetch", "Stance", "StanceConfig",
    "check_fetchable", "check_place_on_a_table", "fetch_skill", "for_one_hand", "plan_fetch", "plan_stance",
]

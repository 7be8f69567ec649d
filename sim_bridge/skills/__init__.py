"""Goal skills run inside the control step: one shape (start, update, cancel, outcome) for every action."""

from sim_bridge.skills.base import GoalVisuals, Skill, SkillOutcome, SkillStatus, Values, visuals_of
from sim_bridge.skills.host import SkillHost, SkillRun
from sim_bridge.skills.locomotion import LEGS, NavigateGoal, NavigateSkill, WalkGoal, WalkSkill

__all__ = [
    "LEGS", "GoalVisuals", "NavigateGoal", "NavigateSkill", "Skill", "SkillHost", "SkillOutcome", "SkillRun", "SkillStatus",
    "Values", "WalkGoal", "WalkSkill", "visuals_of",
]

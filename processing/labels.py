"""The activity classes, in label order (class index = position), the one home of this list: the dataset
store labels items with it, the classifier's outputs follow it, and the motion generators use its names.
Dependency-free, so the CLI's parser can read it before any command runs."""

from typing import Literal, get_args

Activity = Literal["fall", "walk", "stand", "sit", "pick"]  # the type of one name (pydantic fields, mypy)
ACTIVITIES: tuple[str, ...] = get_args(Activity)

__all__ = ["ACTIVITIES", "Activity"]

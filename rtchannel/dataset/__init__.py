"""Dataset generation: augmentation plans (`plan`), one work item (`items`), Dask orchestration (`runner`).

Storage and reading live in the lower layer: `processing.io.dataset_store` (`DatasetReader`).
"""
from rtchannel.dataset.plan import Plan, WorkItem, expand, load_plan
from rtchannel.dataset.runner import RunSummary, run_plan

__all__ = ["Plan", "WorkItem", "expand", "load_plan", "RunSummary", "run_plan"]

"""Tasks by name: what one trial of a study does.

A task is registered with :func:`register` and looked up with :func:`get_task`;
study files refer to tasks by name. Task modules in this package register
themselves on import; :func:`get_task` imports them all first.
"""

from somo_sweep.tasks.registry import TaskResult, TaskSpec, all_tasks, get_task, register

__all__ = ["TaskResult", "TaskSpec", "all_tasks", "get_task", "register"]

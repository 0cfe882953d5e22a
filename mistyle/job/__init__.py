"""One output of ``mistyle-render``: stylize, path trace and write its files, its report and its sheet, and
merge a chunk of a sequence into its folder.

The command line (``mistyle.render_final``) turns options into ``PipelineSettings`` and an ``OutputSpec``
and loads each output's inputs into a ``Job``; this package makes the files from a ``Job`` (``render_job``,
``write_output``, ``render_look_chunk``), so that a farm's workers write outputs as the command does.
"""

from .batch import RenderRequest, render_outputs
from .report import merge_chunk, write_report
from .run import load_job, render_job, render_look_chunk, write_batch_index, write_output
from .spec import SETTING_OPTIONS, Job, OutputSpec, check_same_settings, settings_record

__all__ = [
    "SETTING_OPTIONS",
    "Job",
    "OutputSpec",
    "RenderRequest",
    "check_same_settings",
    "load_job",
    "merge_chunk",
    "render_job",
    "render_look_chunk",
    "render_outputs",
    "settings_record",
    "write_batch_index",
    "write_output",
    "write_report",
]

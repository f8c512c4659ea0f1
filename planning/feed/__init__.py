"""The load-based feed post-processor (seed 001): feeds from a rule by the predicted cutting load,
blocks split where the load changes, and its report; the ``plan feed`` / ``plan simulate`` jobs.
"""

from planning.feed._write import cap_feeds
from planning.feed.force import ForceModel
from planning.feed.job import (
    Job,
    feed_post_options,
    feed_program,
    load_job,
    resolve_rule,
    simulate_job,
)
from planning.feed.post import post_process
from planning.feed.report import write_report
from planning.feed.result import FeedPostOptions, FeedPostResult
from planning.stock.plans import end_mill

__all__ = [
    "FeedPostOptions",
    "ForceModel",
    "FeedPostResult",
    "Job",
    "cap_feeds",
    "end_mill",
    "feed_post_options",
    "feed_program",
    "load_job",
    "post_process",
    "resolve_rule",
    "simulate_job",
    "write_report",
]

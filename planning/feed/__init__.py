"""The load-based feed post-processor (seed 001): feeds from a rule by the predicted cutting load,
blocks split where the load changes, and its report.
"""

from planning.feed.post import FeedPostOptions, FeedPostResult, post_process
from planning.feed.report import write_report

__all__ = ["FeedPostOptions", "FeedPostResult", "post_process", "write_report"]

"""Feed rules (seed 001): cutting load, the rule (load bins to feeds), the base feed from a feed
sweep, and the rule base (SQLite) that stores a rule per machining group.
"""

from analysis.rules.basefeed import BaseFeedSettings, find_base_feed, sweep_runs_from_files
from analysis.rules.load import cutting_load_percent, slot_load_percent
from analysis.rules.rule import FeedRule, derive_rule, load_rule, plot_rule, save_rule
from analysis.rules.rulebase import GroupExistsError, GroupKey, RuleBase, default_path

__all__ = [
    "BaseFeedSettings",
    "FeedRule",
    "GroupExistsError",
    "GroupKey",
    "RuleBase",
    "cutting_load_percent",
    "default_path",
    "derive_rule",
    "find_base_feed",
    "load_rule",
    "plot_rule",
    "save_rule",
    "slot_load_percent",
    "sweep_runs_from_files",
]

"""Feed rules (seed 001): cutting load, the rule (load bins to feeds), the base feed from a feed
sweep, and the rule base (SQLite) that stores a rule per machining group.
"""

from analysis.rules.basefeed import BaseFeedSettings, find_base_feed, sweep_runs_from_files
from analysis.rules.derive import (
    DerivedRule,
    add_rule_file,
    derive_from_sweep,
    export_rule,
    list_groups,
    lookup_group,
    rule_info,
    rule_info_lines,
)
from analysis.rules.load import cutting_load_percent, slot_load_percent
from analysis.rules.rule import FeedRule, derive_rule, load_rule, plot_rule, save_rule
from analysis.rules.rulebase import GroupExistsError, GroupKey, RuleBase, default_path

__all__ = [
    "BaseFeedSettings",
    "DerivedRule",
    "FeedRule",
    "GroupExistsError",
    "GroupKey",
    "RuleBase",
    "add_rule_file",
    "cutting_load_percent",
    "default_path",
    "derive_from_sweep",
    "derive_rule",
    "export_rule",
    "find_base_feed",
    "list_groups",
    "load_rule",
    "lookup_group",
    "plot_rule",
    "rule_info",
    "rule_info_lines",
    "save_rule",
    "slot_load_percent",
    "sweep_runs_from_files",
]

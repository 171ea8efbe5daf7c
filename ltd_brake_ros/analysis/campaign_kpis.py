"""The KPI columns a campaign report summarises, their worse direction and why values miss.

Shared by the report (:mod:`.campaign_report`) and the sensitivity analysis (:mod:`.sensitivity`).
"""
from __future__ import annotations

__all__ = ["KPIS", "NO_VALUE"]

#: KPI columns summarised: column -> (label, worse direction); +1: a larger value is worse,
#: -1: a smaller one is (buff forces are negative: a more negative one is worse). Units are
#: the columns' own (:data:`~ltd_brake_ros.studies.campaign.COLUMNS`).
KPIS = {
    "peak_draft_kN": ("peak draft force", +1),
    "peak_buff_kN": ("peak buff force (negative)", -1),
    "mean_adhesion": ("largest mean utilised adhesion by design (each vehicle's stop from its "
                      "maximum speed)", +1),
    "max_adhesion_demand": ("largest adhesion demand against the rail", +1),
    "stopping_distance_m": ("stopping distance", +1),
}
#: Why a successful run has no value of a KPI (other KPIs: "no value").
NO_VALUE = {
    "stopping_distance_m": "did not stop",
    "mean_adhesion": "not assessed (no braked vehicle)",
}

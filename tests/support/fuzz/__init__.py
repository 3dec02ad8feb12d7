"""Hostile requests for DOM-BOT's services and input topics, sent over real DDS and judged.

* ``harness``: cases, endpoints, sending over DDS, the report, node processes, ``fuzz``;
* ``replies``: each endpoint's outcome names and reply checks (the verdicts);
* ``values``, ``planning``, ``sensing``, ``actions``, ``layer``: the strategies per
  endpoint family (hypothesis), each starting from a valid request and breaking one thing
  at a time, so the right outcome is known; ``random_*`` ones break everything;
* ``services``, ``actions``, ``layer``: the endpoints themselves.
"""

from support.fuzz.actions import action_endpoints
from support.fuzz.harness import Harness, fuzz, fuzzed_nodes, rss_mb
from support.fuzz.layer import layer_endpoints, layer_parameter_cases, path_cases, radius_cases
from support.fuzz.services import service_endpoints

__all__ = [
    "Harness",
    "action_endpoints",
    "fuzz",
    "fuzzed_nodes",
    "layer_endpoints",
    "layer_parameter_cases",
    "path_cases",
    "radius_cases",
    "rss_mb",
    "service_endpoints",
]

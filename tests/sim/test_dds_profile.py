"""sim_node's Fast DDS writer settings (``sim_node.use_dds_profile``): its reliable
writers repair a frame a reader missed within 0.1 s, not at Fast DDS's default 3 s
heartbeat; a profiles file the user chose is left alone."""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from pathlib import Path

from dombot_sim.sim_node import DDS_PROFILES, use_dds_profile

NAMESPACE = {"dds": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}


def test_sim_node_points_fast_dds_at_its_installed_profile() -> None:
    environ: dict[str, str] = {}
    use_dds_profile(environ)
    profile = ElementTree.parse(Path(environ[DDS_PROFILES])).getroot()
    publishers = profile.findall("dds:profiles/dds:publisher", NAMESPACE)
    # one default publisher profile: every writer of the process, the cameras' included
    assert [p.get("is_default_profile") for p in publishers] == ["true"]
    period = publishers[0].find("dds:times/dds:heartbeatPeriod", NAMESPACE)
    seconds = int(period.findtext("dds:sec", namespaces=NAMESPACE))
    seconds += int(period.findtext("dds:nanosec", namespaces=NAMESPACE)) * 1e-9
    assert seconds == 0.1


def test_a_profiles_file_the_user_chose_is_kept() -> None:
    environ = {DDS_PROFILES: "/etc/my_fastdds.xml"}
    use_dds_profile(environ)
    assert environ == {DDS_PROFILES: "/etc/my_fastdds.xml"}

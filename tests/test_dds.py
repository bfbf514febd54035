"""The bundled Fast DDS profiles: applied by default (closed), overridable, accepted by Fast DDS."""

import os
import subprocess
import sys
import xml.etree.ElementTree as ET

from push_ros.dds import (
    CLOSED_RANGE,
    NETWORK_ENV,
    PROFILE_ENV,
    RANGE_ENV,
    apply_default_profile,
    dds_environment,
    network_reason,
    profile_path,
)

PROBE = """
import rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node('dds_profile_probe')
node.create_publisher(String, 'dds_profile_probe', 10)
node.destroy_node()
rclpy.shutdown()
print('created')
"""


def test_default_profile_is_applied_unless_one_is_configured():
    env: dict[str, str] = {}
    assert apply_default_profile(env) == str(profile_path())
    assert env[PROFILE_ENV] == str(profile_path())
    env = {PROFILE_ENV: "/somewhere/else.xml"}
    assert apply_default_profile(env) == "/somewhere/else.xml"


def test_closed_by_default_open_only_by_an_explicit_choice():
    closed = {PROFILE_ENV: str(profile_path()), RANGE_ENV: CLOSED_RANGE}
    assert dds_environment({}) == closed
    assert network_reason({}) is None
    # A range the user set is kept; LOCALHOST and OFF stay closed.
    for scope in ("LOCALHOST", "OFF", "SYSTEM_DEFAULT"):
        assert dds_environment({RANGE_ENV: scope}) == {PROFILE_ENV: str(profile_path())}
    # Opening: PUSHBOT_DDS_NETWORK=1, or the user's own SUBNET, selects the network profile.
    network = {PROFILE_ENV: str(profile_path(network=True))}
    assert dds_environment({NETWORK_ENV: "1"}) == network
    assert dds_environment({RANGE_ENV: "SUBNET"}) == network
    assert network_reason({RANGE_ENV: "SUBNET"}) == f"{RANGE_ENV}=SUBNET"
    assert dds_environment({NETWORK_ENV: "0"}) == closed
    # A profile of the user's own: nothing added.
    assert dds_environment({PROFILE_ENV: "/mine.xml"}) == {}


def test_opening_the_graph_warns(capsys, monkeypatch):
    import push_ros.dds

    monkeypatch.setattr(push_ros.dds, "_warned", False)
    env = {NETWORK_ENV: "1"}
    assert apply_default_profile(env) == str(profile_path(network=True))
    assert "OPEN TO THE NETWORK" in capsys.readouterr().err
    monkeypatch.setattr(push_ros.dds, "_warned", False)
    apply_default_profile({})
    assert capsys.readouterr().err == ""


def _elements(path, drop=""):
    """The profile's XML without comments, ``drop`` elements removed, as bytes."""
    root = ET.parse(path).getroot()  # ElementTree drops comments
    for parent in root.iter():
        for child in list(parent):
            if drop and child.tag.endswith(drop):
                parent.remove(child)
    for element in root.iter():
        element.tail = (element.tail or "").strip()
        element.text = (element.text or "").strip()
    return ET.tostring(root)


def test_the_two_profiles_differ_only_by_the_loopback_allowlist():
    ns = "{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}"
    udp = [d for d in ET.parse(profile_path()).getroot().iter(f"{ns}transport_descriptor")
           if d.findtext(f"{ns}type") == "UDPv4"]
    assert len(udp) == 1
    assert [a.text for a in udp[0].iter(f"{ns}address")] == ["127.0.0.1"]
    assert udp[0].find(f"{ns}interfaceWhiteList") is not None
    assert _elements(profile_path(), drop="interfaceWhiteList") == _elements(
        profile_path(network=True))
    assert b"interfaceWhiteList" not in _elements(profile_path(network=True))


def test_the_session_uses_the_profile():
    # tests/conftest.py applies it before anything starts rclpy.
    assert os.environ[PROFILE_ENV] == str(profile_path())


def _create_publisher_with(profile):
    env = dict(os.environ, **{PROFILE_ENV: str(profile)})
    return subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True,
                          text=True, timeout=60, check=False)


def test_fast_dds_parses_the_bundled_profile_without_errors(tmp_path):
    ok = _create_publisher_with(profile_path())
    assert ok.returncode == 0 and "created" in ok.stdout, ok.stderr
    # Fast DDS logs parser errors on stdout.
    assert "XMLPARSER" not in ok.stdout + ok.stderr, ok.stdout + ok.stderr
    # Control: a profile with a misspelt element is reported by the same parser, so the check
    # above can fail.
    broken = tmp_path / "broken.xml"
    broken.write_text(profile_path().read_text().replace("heartbeatPeriod", "heartbeatPeriodX"))
    bad = _create_publisher_with(broken)
    assert "XMLPARSER" in bad.stdout + bad.stderr


def test_fast_dds_parses_the_network_profile_without_errors():
    ok = _create_publisher_with(profile_path(network=True))
    assert ok.returncode == 0 and "created" in ok.stdout, ok.stderr
    assert "XMLPARSER" not in ok.stdout + ok.stderr, ok.stdout + ok.stderr

"""The bundled Fast DDS profile: applied by default, overridable, and accepted by Fast DDS."""

import os
import subprocess
import sys

from pushbot.dds import PROFILE_ENV, apply_default_profile, profile_path

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
    env = {PROFILE_ENV: '/somewhere/else.xml'}
    assert apply_default_profile(env) == '/somewhere/else.xml'


def test_the_session_uses_the_profile():
    # tests/conftest.py applies it before anything starts rclpy.
    assert os.environ[PROFILE_ENV] == str(profile_path())


def _create_publisher_with(profile):
    env = dict(os.environ, **{PROFILE_ENV: str(profile)})
    return subprocess.run([sys.executable, '-c', PROBE], env=env, capture_output=True,
                          text=True, timeout=60, check=False)


def test_fast_dds_parses_the_bundled_profile_without_errors(tmp_path):
    ok = _create_publisher_with(profile_path())
    assert ok.returncode == 0 and 'created' in ok.stdout, ok.stderr
    # Fast DDS logs parser errors on stdout.
    assert 'XMLPARSER' not in ok.stdout + ok.stderr, ok.stdout + ok.stderr
    # Control: a profile with a misspelt element is reported by the same parser, so the check
    # above can fail.
    broken = tmp_path / 'broken.xml'
    broken.write_text(profile_path().read_text().replace('heartbeatPeriod', 'heartbeatPeriodX'))
    bad = _create_publisher_with(broken)
    assert 'XMLPARSER' in bad.stdout + bad.stderr

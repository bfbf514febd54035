from glob import glob

from setuptools import find_packages, setup

package_name = "pushbot_bringup"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        # `ros2 launch pushbot_bringup pushbot.launch.py` finds the launch file here, and the
        # launch file its parameter files next to it (share/pushbot_bringup/config).
        ("share/" + package_name + "/launch", sorted(glob("launch/*.launch.py"))),
        ("share/" + package_name + "/config", sorted(glob("config/*.yaml"))),
        # The RViz config of the graph: rviz2 -d <share>/pushbot_bringup/rviz/pushbot.rviz
        ("share/" + package_name + "/rviz", sorted(glob("rviz/*.rviz"))),
    ],
    # Runtime dependencies come from requirements.txt (pip) or package.xml (rosdep);
    # ament_python packages list only setuptools here.
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="pushbot developers",
    maintainer_email="pushbot@example.com",
    description="Launch file and per-node parameter files of the pushbot graph.",
    license="Apache-2.0",
)

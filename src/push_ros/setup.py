from setuptools import find_packages, setup

package_name = "push_ros"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    # The Fast DDS profiles of push_ros.dds (importlib.resources), also under share/ for users
    # who export FASTRTPS_DEFAULT_PROFILES_FILE themselves.
    package_data={package_name: ["data/*.xml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/dds", ["push_ros/data/fastdds.xml",
                                             "push_ros/data/fastdds_network.xml"]),
    ],
    # Runtime dependencies come from requirements.txt (pip) or package.xml (rosdep);
    # ament_python packages list only setuptools here.
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="pushbot developers",
    maintainer_email="pushbot@example.com",
    description="ROS-side library of the pushbot nodes: message codecs, QoS, node helpers.",
    license="Apache-2.0",
)

from setuptools import find_packages, setup

package_name = "push_executor"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    # Runtime dependencies come from requirements.txt (pip) or package.xml (rosdep);
    # ament_python packages list only setuptools here.
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="pushbot developers",
    maintainer_email="pushbot@example.com",
    description="Executes planned pushes on a ros2_control arm (joint trajectories).",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "push_executor_node = push_executor.push_executor_node:main"
        ],
    },
)

from setuptools import find_packages, setup

package_name = "push_planner"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    # Weights of the learned affordance model and its model card.
    package_data={"push_planner.models": ["*.pt", "MODEL_CARD.md"]},
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
    description="Affordance-based greedy push planner.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "planner_node = push_planner.planner_node:main"
        ],
    },
)

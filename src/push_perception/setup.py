from setuptools import find_packages, setup

package_name = "push_perception"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    # The trained segmentation weights and their model card travel with the package.
    package_data={package_name: ["models/*.pt", "models/*.md", "models/*.json"]},
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
    description="Segmentation, object pose and outline from RGB-D frames.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "segmentation_node = push_perception.segmentation_node:main"
        ],
    },
)

from setuptools import find_packages, setup

package_name = "pushbot"

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
    # `pushbot eval push --ray ADDRESS` runs the trials as Ray tasks, for users who outgrow one
    # machine (pip install 'pushbot[ray]'; the repository's .venv has it from requirements.txt);
    # the default engine is local worker processes.
    # `pushbot eval pusht`: gym-pusht and what it needs at run time. gym-pusht
    # 0.1.8 also requires opencv-python<5; where opencv-python-headless 5 is installed (this
    # repository's .venv) install gym-pusht with --no-deps instead, as `make venv` does.
    extras_require={"ray": ["ray>=2.9"],
                    "pusht": ["gym-pusht==0.1.8", "gymnasium>=0.29.1,<2", "pygame>=2.5.2,<2.7",
                              "pymunk>=6.6,<7", "shapely>=2.0.3,<3"]},
    zip_safe=True,
    maintainer="pushbot developers",
    maintainer_email="pushbot@example.com",
    description="The pushbot command line.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "pushbot = pushbot.cli:main"
        ],
    },
)

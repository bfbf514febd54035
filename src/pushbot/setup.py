from setuptools import find_packages, setup

package_name = 'pushbot'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={'pushbot': ['data/*.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    # Runtime dependencies come from requirements.txt (pip) or package.xml (rosdep);
    # ament_python packages list only setuptools here.
    install_requires=['setuptools'],
    # `pushbot eval push --ray ADDRESS` runs the trials as Ray tasks, for users who outgrow one
    # machine (pip install 'pushbot[ray]'; the repository's .venv has it from requirements.txt);
    # the default engine is local worker processes.
    extras_require={'ray': ['ray>=2.9']},
    zip_safe=True,
    maintainer='pushbot developers',
    maintainer_email='pushbot@example.com',
    description='The pushbot command line.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'pushbot = pushbot.cli:main'
        ],
    },
)

"""ament_python packaging for geodesic_planner (also a plain pip-installable library)."""
from glob import glob

from setuptools import Extension, find_packages, setup

PACKAGE = 'geodesic_planner'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'benchmarks', 'tools', 'tools.*', 'msg_examples',
                                    'msg_examples.*']),
    package_data={PACKAGE: ['py.typed', 'data/*.urdf']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/launch', sorted(glob('launch/*.launch.py'))),
        ('share/' + PACKAGE + '/config', sorted(glob('config/*.yaml'))),
    ],
    # The compiled kernels (plain C, loaded with ctypes; core/compiled.py). Optional: without a
    # compiler the build goes on and the library runs its numpy code, with the same results.
    ext_modules=[Extension(PACKAGE + '.core._kernels', sources=[PACKAGE + '/core/_kernels.c',
                                                               PACKAGE + '/core/_kernels_timing.c'],
                           depends=[PACKAGE + '/core/_kernels.h'],
                           extra_compile_args=['-O2', '-fno-math-errno', '-ffp-contract=off'], optional=True)],
    python_requires='>=3.10',
    install_requires=['numpy>=1.24', 'scipy>=1.10', 'pyyaml>=6', 'pin>=3.0'],
    extras_require={
        'plot': ['matplotlib>=3.6'],
        'bag': ['rosbags>=0.11'],
        'batch': ['ray>=2.60', 'pyarrow>=26'],   # geodesic-plan batch
    },
    zip_safe=True,
    maintainer='geodesic_planner developers',
    maintainer_email='dev@geodesic-planner.invalid',
    description='Geodesic trajectory planning for robot arms (Chen, Li & Tang 2016).',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'geodesic-plan = geodesic_planner.cli.plan:plan_main',
            'geodesic-compare = geodesic_planner.cli.compare:main',
            'geodesic-bag = geodesic_planner.cli.bag:main',
            'geodesic_planner_node = geodesic_planner.ros.planner_node:main',
            'trajectory_processor_node = geodesic_planner.ros.processor_node:main',
        ],
    },
)

"""The rosbag2 storage plugins a bag can be recorded with, and their file suffixes.

A leaf of its own, so that a parameter schema can name them without loading the bag modules
(rosbags, mcap: about 0.1 s of a node's start-up that never records).
"""
from __future__ import annotations

#: Storage plugins, as rosbag2 names them.
STORAGES = ('mcap', 'sqlite3')
#: The storage file's suffix per plugin.
STORAGE_SUFFIX = {'mcap': '.mcap', 'sqlite3': '.db3'}

__all__ = ['STORAGES', 'STORAGE_SUFFIX']

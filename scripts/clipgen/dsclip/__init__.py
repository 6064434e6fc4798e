# SPDX-License-Identifier: Apache-2.0
"""dsclip: the project's own generator of simulated tight-cloth clips (run inside Blender).

Modules without bpy (importable by any Python with numpy): config, curves, shapes, weights,
moves, cachefiles. The one module that needs Blender: blendscene.
"""

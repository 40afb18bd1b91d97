"""The lightmap benchmark's anchor: Blender's Cycles ambient-occlusion bake of an OBJ's UV set, as
a Blender user would bake it (Render Properties > Bake > Ambient Occlusion), run headless:

    blender -b --factory-startup --python bench/cycles_ao_bake.py -- SCENE.obj SIZE SAMPLES OUT.npy

The AO range is the whole scene (the world's AO distance set beyond the scene's size), the
margin 8 texels (extend: prtbake's default dilation), the CPU device with every core, every
sample taken (no adaptive sampling, no denoising), smooth shading on the OBJ's normals. Writes
the baked image as a SIZE x SIZE float32 array in prtbake's row order (row 0 at OBJ v = 1,
the image's top; Blender's pixel rows run bottom-up) and prints the bake's own seconds.
"""
import sys
import time

import bpy
import numpy as np


def main():
    scene_path, size, samples, out = sys.argv[sys.argv.index("--") + 1:]
    size, samples = int(size), int(samples)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=scene_path)
    objects = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    if len(objects) != 1:
        bpy.ops.object.select_all(action="DESELECT")
        for o in objects:
            o.select_set(True)
        bpy.context.view_layer.objects.active = objects[0]
        bpy.ops.object.join()
    obj = bpy.context.view_layer.objects.active or objects[0]
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    # The OBJ's vn as the shading normals (the importer keeps them as custom normals; smooth
    # shading makes Cycles use them, as prtbake does), not each polygon's flat normal.
    bpy.ops.object.shade_smooth()

    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False  # every texel takes all its samples, as prtbake does
    scene.render.threads_mode = "AUTO"
    if scene.world is None:
        scene.world = bpy.data.worlds.new("World")
    scene.world.light_settings.distance = 1.0e4  # the whole scene (it spans 20 units)
    scene.render.bake.margin = 8
    scene.render.bake.margin_type = "EXTEND"

    image = bpy.data.images.new("ao", width=size, height=size, float_buffer=True, alpha=False)
    material = bpy.data.materials.new("bake")
    material.use_nodes = True
    node = material.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    material.node_tree.nodes.active = node
    obj.data.materials.clear()
    obj.data.materials.append(material)

    t0 = time.monotonic()
    bpy.ops.object.bake(type="AO")
    seconds = time.monotonic() - t0
    pixels = np.empty(size * size * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    ao = pixels.reshape(size, size, 4)[::-1, :, 0].copy()  # bottom-up rows to top-down
    np.save(out, ao)
    print("cycles_bake_seconds %.3f" % seconds)


main()

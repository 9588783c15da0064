"""Imports a motion file into Blender (the `bpy` module from PyPI) and prints what a user would
check, as one JSON line: the armature's bone count, the frame range and rate, and per sampled
frame the world positions (metres, Blender's Z-up) of the root, head, feet and hips.

Usage: python blender_import.py FILE.(bvh|gltf|glb|fbx) STEP [RENDER.png]

With RENDER.png it also renders the character at the first frame (Workbench, headless).

BVH is imported with scale 0.01 (locap solve writes centimetres) and Blender's defaults for
the axes (BVH Y-up, -Z forward); glTF and FBX with the importers' defaults, the scene's frame
rate set from the file where the format records it (FBX) and to the BVH's otherwise (glTF has
times, not frames: the rate is passed in the environment variable LOCAP_FPS).
"""

import json
import os
import sys

import bpy


def main():
    path, step = sys.argv[1], int(sys.argv[2])
    render = sys.argv[3] if len(sys.argv) > 3 else None
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    ext = os.path.splitext(path)[1].lower()
    if ext == ".bvh":
        bpy.ops.import_anim.bvh(filepath=path, global_scale=0.01, update_scene_fps=True, update_scene_duration=True)
    elif ext in (".gltf", ".glb"):
        scene.render.fps = int(os.environ.get("LOCAP_FPS", "120"))
        scene.render.fps_base = 1.0
        bpy.ops.import_scene.gltf(filepath=path)
    elif ext == ".fbx":
        bpy.ops.import_scene.fbx(filepath=path, use_anim=True)
    else:
        raise SystemExit(f"unknown format {ext}")
    armatures = [o for o in scene.objects if o.type == "ARMATURE"]
    if len(armatures) != 1:
        raise SystemExit(f"expected one armature, found {[o.name for o in scene.objects]}")
    arm = armatures[0]
    action = arm.animation_data.action if arm.animation_data else None
    if action is None:
        raise SystemExit("the armature has no animation")
    start, end = (int(round(v)) for v in action.frame_range)
    bones = arm.pose.bones
    root = [b for b in bones if b.parent is None]
    if len(root) != 1:
        raise SystemExit(f"expected one root bone, found {[b.name for b in root]}")

    def world(name):
        b = bones.get(name)
        return None if b is None else list(arm.matrix_world @ b.head)

    frames = []
    for frame in range(start, end + 1, step):
        scene.frame_set(frame)
        frames.append(
            {
                "frame": frame - start,
                "root": world(root[0].name),
                "head": world("head"),
                "lfoot": world("lfoot"),
                "rfoot": world("rfoot"),
                "lfemur": world("lfemur"),
                "rfemur": world("rfemur"),
            }
        )
    if render:
        render_still(scene, arm, render)
    print(
        json.dumps(
            {
                "bones": len(bones),
                "root": root[0].name,
                "start": start,
                "end": end,
                "fps": scene.render.fps / scene.render.fps_base,
                "frames": frames,
            }
        )
    )


def render_still(scene, arm, path):
    """A small Workbench render of the character at frame 1: each bone a tube, each joint a
    ball, over a floor at Z = 0, seen from the front-right."""
    import mathutils

    scene.frame_set(scene.frame_start)
    material = bpy.data.materials.new("bone")
    material.diffuse_color = (0.85, 0.3, 0.7, 1.0)
    for bone in arm.pose.bones:
        head, tail = arm.matrix_world @ bone.head, arm.matrix_world @ bone.tail
        along = tail - head
        if along.length < 1e-4:
            continue
        bpy.ops.mesh.primitive_cylinder_add(radius=0.02, depth=along.length, location=(head + tail) / 2)
        tube = bpy.context.object
        tube.rotation_euler = along.to_track_quat("Z", "Y").to_euler()
        tube.data.materials.append(material)
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.03, location=head)
        bpy.context.object.data.materials.append(material)
    centre = arm.matrix_world @ arm.pose.bones[0].head
    bpy.ops.mesh.primitive_plane_add(size=6, location=(centre.x, centre.y, 0.0))
    camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    scene.collection.objects.link(camera)
    camera.location = centre + mathutils.Vector((2.5, -3.5, 0.5))
    camera.rotation_euler = (centre - camera.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.display.shading.light = "STUDIO"
    scene.display.shading.color_type = "MATERIAL"
    scene.render.resolution_x, scene.render.resolution_y = 400, 400
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


main()

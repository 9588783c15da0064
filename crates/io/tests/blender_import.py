"""Imports a motion file into Blender (the `bpy` module from PyPI) and prints what a user would
check, as one JSON line: the armature's bone count, the frame range and rate, and per sampled
frame the world positions (metres, Blender's Z-up) of the root, head, feet and hips.

Usage: python blender_import.py FILE.(bvh|gltf|glb|fbx) STEP [RENDER.png]

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
    """A small Workbench render of the armature at frame 1, seen from the front-left."""
    import mathutils

    scene.frame_set(1)
    arm.data.display_type = "STICK"
    arm.show_in_front = True
    centre = arm.matrix_world @ arm.pose.bones[0].head
    cam_data = bpy.data.cameras.new("camera")
    cam = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(cam)
    cam.location = centre + mathutils.Vector((3.0, -4.0, 0.6))
    cam.rotation_euler = (centre - cam.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = 480, 480
    scene.render.filepath = path
    bpy.ops.render.opengl(write_still=True)


main()

"""Frames from a camera that follows the robot, for ``render_mode="rgb_array"`` (single and batched envs).

``mujoco.Renderer`` with a tracking ``MjvCamera``. Gymnasium's ``MujocoRenderer`` is not used for frames: from
Gymnasium 1.x its offscreen path resolves a missing model camera to id -1 and then sets a free camera on every
frame, so a tracking configuration is dropped and a walking robot leaves the picture. Its window viewer (``human``)
keeps the configuration and is still used for that mode.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np


def tracking_camera(model: mujoco.MjModel, config: dict[str, Any], body: int) -> mujoco.MjvCamera:
    """A camera following ``body``, from the model's default free camera with ``config``'s fields set."""
    camera = mujoco.MjvCamera()
    mujoco.mjv_defaultFreeCamera(model, camera)
    for key, value in {**config, "type": mujoco.mjtCamera.mjCAMERA_TRACKING, "trackbodyid": body}.items():
        setattr(camera, key, value)
    return camera


class FrameRenderer:
    """RGB frames of ``model`` at ``width`` x ``height`` from ``camera``.

    ``mjv_updateScene`` lays an infinite plane (the floor) out around the scene's camera as the previous frame left
    it, and its extent is the far clip plane (``vis.map.zfar`` times the model's extent, a few metres for a small
    robot): after a jump of the camera (the first frame of a robot far from the origin, the first after a reset
    from there) the floor would lie beyond the far plane and the frame come out black. The scene's camera is
    brought to the present first.
    """

    def __init__(self, model: mujoco.MjModel, camera: mujoco.MjvCamera, width: int, height: int):
        vis = model.vis.global_  # the offscreen buffer must hold the frame
        vis.offwidth, vis.offheight = max(vis.offwidth, width), max(vis.offheight, height)
        self.camera = camera
        self._model = model
        try:
            self._renderer = mujoco.Renderer(model, height, width)
        except mujoco.FatalError as exc:  # no OpenGL: MuJoCo chose its windowed backend, and there is no display
            raise RuntimeError(
                f"frames need an OpenGL context and MuJoCo found none ({exc}); on a machine without a display, set "
                "MUJOCO_GL=egl (or osmesa) in the environment before mujoco is first imported"
            ) from exc

    def render(self, data: mujoco.MjData) -> np.ndarray:
        mujoco.mjv_updateCamera(self._model, data, self.camera, self._renderer.scene)
        self._renderer.update_scene(data, self.camera)
        return self._renderer.render()

    def close(self) -> None:
        self._renderer.close()

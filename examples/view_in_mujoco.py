"""Look at a chain in MuJoCo: export it with ``to_mjcf`` and open the viewer, or render a PNG.

    python examples/view_in_mujoco.py            # viewer if a display exists, else writes files
    python examples/view_in_mujoco.py --headless # always write chain.xml and chain.png

With a display, MuJoCo's passive viewer shows the double cartpole starting near upright and
falling under gravity (MuJoCo's own Euler integrator, the one ``lg.SemiImplicitEuler()``
reproduces). Headless, it writes the MJCF and, if offscreen rendering works (EGL/OSMesa, set
``MUJOCO_GL=egl`` or ``osmesa``), a PNG of the first frame.
"""

import argparse
import os
import time

import mujoco
import numpy as np

import lagrange as lg
from lagrange.interop.mjcf import to_mjcf


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--headless", action="store_true", help="write chain.xml and chain.png, no viewer")
    parser.add_argument("--out", default=".", help="folder for chain.xml / chain.png")
    args = parser.parse_args()

    chain = lg.systems.double_cartpole()
    xml = to_mjcf(chain, timestep=0.01 / 12, name="double_cartpole", radius=0.04)
    # scenery for the eye only (no mass, no contacts): a light and the cart's rail
    xml = xml.replace(
        "<worldbody>",
        '<worldbody>\n    <light pos="0 -4 4" dir="0 1 -1"/>'
        '\n    <geom type="capsule" fromto="-3 0 0 3 0 0" size="0.01" rgba=".6 .6 .6 1" contype="0" conaffinity="0"/>',
    )
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[:] = np.array([0.0, np.pi - 0.05, 0.05])  # poles nearly upright
    mujoco.mj_forward(model, data)

    if not args.headless and (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        from mujoco import viewer as mujoco_viewer

        with mujoco_viewer.launch_passive(model, data) as viewer:
            while viewer.is_running():
                mujoco.mj_step(model, data)
                viewer.sync()
                time.sleep(model.opt.timestep)
        return

    os.makedirs(args.out, exist_ok=True)
    path = os.path.join(args.out, "chain.xml")
    with open(path, "w") as f:
        f.write(xml)
    print(f"wrote {path}")
    try:
        camera = mujoco.MjvCamera()
        camera.lookat[:] = [0.0, 0.0, 0.5]
        camera.distance, camera.azimuth, camera.elevation = 6.0, 90.0, 0.0  # looking along +y at x-z
        with mujoco.Renderer(model, height=480, width=640) as renderer:
            renderer.update_scene(data, camera)
            pixels = renderer.render()
    except Exception as err:  # no OpenGL context headless: say so, the XML is still there
        print(f"offscreen rendering unavailable ({type(err).__name__}: {err}); open {path} in MuJoCo's simulate")
        return
    from PIL import Image

    png = os.path.join(args.out, "chain.png")
    Image.fromarray(pixels).save(png)
    print(f"wrote {png}")


if __name__ == "__main__":
    main()

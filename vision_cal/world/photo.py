"""Photographs of the sheet: a pyrender pinhole render plus lens, vignetting, noise and JPEG.

Conventions
-----------
- Cameras follow OpenCV (see :mod:`vision_cal.world.camera`): ``T_cam_sheet`` maps sheet
  points (x, y, z) (z up out of the paper, mm) to the camera frame (x right, y down, z
  forward); pixels are (u, v) = (col, row), integer at pixel centres.
- The sheet is a textured quad spanning ``extent_mm`` on z = 0, drawn with pyrender's FLAT
  (unlit) shader, so a texel's RGB reaches the image unchanged (no lighting, no sRGB
  conversion). The texture follows the pixel convention of :mod:`vision_cal.world.sheet`.
- Sampling: the scene is rendered at ``supersample`` times the image size with
  trilinear-mipmapped texture look-ups at the (supersampled) pixel centres, then averaged
  down in s x s blocks (cv2.INTER_AREA). The camera matrix of the big render is
  ``K_s = S K`` with ``u_s = s u + (s - 1) / 2``, so every output pixel is the area average
  over its own footprint. pyrender's ``IntrinsicsCamera`` takes an OpenGL principal point,
  which is the OpenCV one + 0.5. ``bench/render.py --accuracy`` prints where rendered dot
  centres land against ``cv2.projectPoints`` (flat, tilted 20-30 deg, with a lens);
  tests/world/test_photo.py bounds them. Mean colours come out slightly brighter than the
  texture's (llvmpipe rounds up when it builds mipmaps and filters), equally in all
  channels.
- Texture resolution: aim for about 2 texels per supersampled pixel (8 px/mm for an A2
  sheet in a 2000 x 1500 photo); the texture must fit ``max_texture_px`` (OpenGL limit).
- The arm (optional) is a set of boxes and a pen-holder cylinder with lighting baked into
  vertex colours (ambient + several directional lights, Lambertian + a little specular),
  drawn in the same FLAT pass. With ``lights="default"`` it casts soft shadows on the
  paper: the footprint of each part projected along the key light, blurred by its height
  and multiplied onto the sheet pixels only (``SHADOW_STRENGTH`` at most). Everything else
  on the sheet keeps the texture's exact colours.
- ``photograph`` applies lens distortion (``camera.distort_image``, on the supersampled
  render before it is averaged down, like a lens in front of a sensor), then vignetting
  (``gain = 1 - v (1 - cos^4 theta) / (1 - cos^4 theta_corner)``: ``v`` is the fraction of
  light lost in the image corners), sensor noise (Gaussian, std ``noise_sigma *
  sqrt(0.25 + 0.75 I/255)`` grey levels: signal-dependent like shot noise) and an optional
  JPEG round trip, in that order.
- Lenses: ``dist`` is any of OpenCV's models (4, 5, 8, 12 or 14 coefficients: radial k1 k2
  k3 [k4 k5 k6], tangential p1 p2, thin prism s1 s2 s3 s4, tilt); ``camera.phone_lens`` builds
  the terms beyond k1 k2 (decentring and thin prism, what a phone's stacked plastic
  elements add) from their size in pixels at the image corner.
- Real photos (issue 28, ``bench/real_photos.py --fixture``): OpenCV's ChArUco photos
  (fixtures/real_charuco_opencv, 640 x 480, JPEG quality 95 by their quantisation
  tables) leave 0.34-0.54 px per view after OpenCV's 5-term lens on vision-cal's corners
  (0.73-1.0 px on OpenCV's own corners; 0.38-0.56 px after vision-cal's homography alone);
  the tangential and thin-prism terms take 0.11 px RMS of it (0.417 px with k1 k2 k3
  only, 0.401 with 12 terms). Those corners reach about 60 % of the 400 px
  half-diagonal; terms growing with r^2 then give about 0.11 / 0.6^2 = 0.3 px at the
  corner, 0.2 px for each family: ``PHONE_TANGENTIAL_PX`` and ``PHONE_PRISM_PX`` (0.6 px
  per 1000 px of half-diagonal each) scale that to another frame. Five photos of one
  board do not pin the terms themselves (the 12-term fit trades them against the focal
  length), only their share of the residual.
"""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import functools  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import zlib  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

if not hasattr(np, "infty"):  # pyrender 0.1.45 still uses np.infty (removed in numpy 2)
    np.infty = np.inf

import pyrender  # noqa: E402
import trimesh  # noqa: E402

from vision_cal.errors import VisionCalError  # noqa: E402
from vision_cal.world.camera import distort_image  # noqa: E402

BACKGROUND_RGB = (70, 66, 60)        # the table around the sheet
ARM_RGB = (0.62, 0.64, 0.68)         # link boxes (albedo)
HOLDER_RGB = (0.22, 0.22, 0.25)      # pen holder cylinder
SHADOW_STRENGTH = 0.35               # fraction of light removed in the darkest shadow
SHADOW_SCALE = 4                     # shadows are drawn at 1/4 of the render resolution
LENS_INTERPOLATION = "linear"        # distort_image on the supersampled render (see photograph)
# directions the light travels (sheet frame, pointing down), intensities
DEFAULT_LIGHTS = (((-0.35, -0.45, -1.0), 0.55), ((0.6, 0.2, -1.0), 0.25),
                  ((0.1, -0.9, -0.4), 0.15))
AMBIENT = 0.25
_MIN_FILTER = pyrender.GLTF.LINEAR_MIPMAP_LINEAR


class _BiasedTexture(pyrender.Texture):
    """A pyrender texture whose mipmap level is chosen ``lod_bias`` levels coarser."""

    def __init__(self, *args, lod_bias: float = 0.0, **kwargs):
        super().__init__(*args, **kwargs)
        self.lod_bias = float(lod_bias)

    def _add_to_context(self):
        super()._add_to_context()
        # OpenGL needs the EGL platform set up: loaded here, when rendering
        from OpenGL import GL

        GL.glBindTexture(GL.GL_TEXTURE_2D, self._texid)
        GL.glTexParameterf(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_LOD_BIAS, self.lod_bias)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)


def _read_color_only(renderer, scene, flags):
    """pyrender's ``Renderer._read_main_framebuffer`` without the depth buffer: the same
    colour bytes (resolve the multisampled buffer, read back), ``(rgba, None)`` with
    ``rgba`` (h, w, 4) uint8 still bottom-up (OpenGL's row order; pyrender's image is
    ``np.flip(rgba, axis=0)[..., :3]``). The depth read-back and its linearisation over
    every supersampled pixel cost more than the colour; a photo without the arm's shadows
    never uses them. RGBA reads back at twice the speed of RGB (no repacking)."""
    from OpenGL import GL

    width, height = renderer._main_fb_dims[0], renderer._main_fb_dims[1]
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, renderer._main_fb_ms)
    GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, renderer._main_fb)
    GL.glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL.GL_COLOR_BUFFER_BIT,
                         GL.GL_LINEAR)
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, renderer._main_fb)
    buf = GL.glReadPixels(0, 0, width, height, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE)
    return np.frombuffer(buf, dtype=np.uint8).reshape((height, width, 4)), None


#: a shadow weaker than this changes no pixel: 255 (1 - SHADOW_STRENGTH m) rounds to 255
SHADOW_VISIBLE = 0.005


def _shadow_window(mask, hs: int, ws: int, q: int):
    """The full-resolution window ``(r0, r1, c0, c1)`` outside which the shadow ``mask``
    (drawn at 1/``q`` resolution) changes no pixel, and the mask resized there; None: no
    shadow anywhere. The values are those of ``cv2.resize(mask, (ws, hs), INTER_LINEAR)``
    over the whole image: a full pixel mixes its two nearest small pixels per axis, so away
    from the crop's own border (one small pixel of padding) the crop resizes the same; a
    pixel whose small neighbours are all below ``SHADOW_VISIBLE`` keeps its colour
    (``np.rint(c * (1 - SHADOW_STRENGTH m)) == c`` for c <= 255). When ``q`` does not
    divide the image the whole image is the window."""
    if hs != q * mask.shape[0] or ws != q * mask.shape[1]:
        return (0, hs, 0, ws), cv2.resize(mask, (ws, hs), interpolation=cv2.INTER_LINEAR)
    rows = np.flatnonzero(mask.max(axis=1) >= SHADOW_VISIBLE)
    cols = np.flatnonzero(mask.max(axis=0) >= SHADOW_VISIBLE)
    if rows.size == 0:
        return None
    hq, wq = mask.shape
    i0, i1 = max(rows[0] - 2, 0), min(rows[-1] + 3, hq)      # small crop, 2 px padding
    j0, j1 = max(cols[0] - 2, 0), min(cols[-1] + 3, wq)
    big = cv2.resize(np.ascontiguousarray(mask[i0:i1, j0:j1]), ((j1 - j0) * q, (i1 - i0) * q),
                     interpolation=cv2.INTER_LINEAR)
    # full pixels whose two small neighbours per axis both lie in the crop
    r0 = 0 if i0 == 0 else (i0 + 1) * q
    r1 = hs if i1 == hq else (i1 - 1) * q
    c0 = 0 if j0 == 0 else (j0 + 1) * q
    c1 = ws if j1 == wq else (j1 - 1) * q
    return (r0, r1, c0, c1), big[r0 - i0 * q:r1 - i0 * q, c0 - j0 * q:c1 - j0 * q]


def _read_depth_window(renderer, r0: int, r1: int, c0: int, c1: int, znear: float,
                       zfar: float) -> np.ndarray:
    """The linear depth (mm; 0 where nothing was drawn) of rows ``r0:r1``, columns
    ``c0:c1`` (top-down image rows) of pyrender's last render: pyrender's own
    ``_read_main_framebuffer`` depth (multisample resolve, read-back, linearisation)
    restricted to the window, the same values at a fraction of the cost."""
    from OpenGL import GL

    height = renderer._main_fb_dims[1]
    y0, y1 = height - r1, height - r0                # OpenGL rows count from the bottom
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, renderer._main_fb_ms)
    GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, renderer._main_fb)
    GL.glBlitFramebuffer(c0, y0, c1, y1, c0, y0, c1, y1, GL.GL_DEPTH_BUFFER_BIT, GL.GL_NEAREST)
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, renderer._main_fb)
    buf = GL.glReadPixels(c0, y0, c1 - c0, y1 - y0, GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT)
    d = np.flip(np.frombuffer(buf, dtype=np.float32).reshape((y1 - y0, c1 - c0)), axis=0)
    inf = d == 1.0
    d = 2.0 * d - 1.0
    noninf = np.logical_not(inf)
    d[noninf] = (2.0 * znear * zfar) / (zfar + znear - d[noninf] * (zfar - znear))
    d[inf] = 0.0
    return d


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


class Photographer:
    """Renders photos of size ``size_px = (w, h)`` with camera matrix ``K`` (pinhole).

    Build one per image size and K and reuse it (it owns an OpenGL context; ``close()``
    frees it without disturbing other Photographers in the process). The sheet
    texture is uploaded once and kept while the same texture content is rendered again;
    a texture of the same size that differs in a few texels (a series photo's new mark)
    has only their rectangle uploaded, then its mipmaps rebuilt (the same photo).
    ``last_timing`` holds the seconds of the last call split into ``texture_upload_s``,
    ``render_s`` (pyrender and read-back), ``downsample_s``, ``post_s`` (distortion,
    vignetting, noise, JPEG) and ``total_s``.
    """

    def __init__(self, *, size_px, K, supersample: int = 2, znear_mm: float = 10.0,
                 zfar_mm: float = 1.0e5, lod_bias: float = 0.0):
        self.size_px = (int(size_px[0]), int(size_px[1]))
        self.K = np.asarray(K, dtype=float).reshape(3, 3)
        self.supersample = int(supersample)
        self.lod_bias = float(lod_bias)
        if self.supersample < 1:
            raise VisionCalError("expected a supersample factor >= 1", field="supersample")
        s = self.supersample
        w, h = self.size_px
        Ks = self._supersampled(self.K)
        self.K_render = Ks
        self._renderer = pyrender.OffscreenRenderer(w * s, h * s)
        # OpenGL needs the EGL platform set up: loaded here, when rendering
        from OpenGL import GL

        self._renderer._platform.make_current()
        GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        self.max_texture_px = int(GL.glGetIntegerv(GL.GL_MAX_TEXTURE_SIZE))
        bg = np.array(BACKGROUND_RGB, dtype=float) / 255.0
        self._scene = pyrender.Scene(bg_color=np.append(bg, 1.0), ambient_light=np.ones(3))
        self._camera = pyrender.IntrinsicsCamera(Ks[0, 0], Ks[1, 1], Ks[0, 2] + 0.5,
                                                 Ks[1, 2] + 0.5, znear=znear_mm,
                                                 zfar=zfar_mm)
        self._cam_node = self._scene.add(self._camera, pose=np.eye(4))
        self._sheet_node = None
        self._sheet_texture = None
        self._sheet_key = None
        self._arm_node = None
        self.last_timing: dict[str, float] = {}

    def close(self) -> None:
        """Release this Photographer's OpenGL context (others stay usable).

        pyrender's own ``OffscreenRenderer.delete`` terminates the shared EGL display, which
        kills every other renderer in the process; this destroys only our context.
        """
        r, self._renderer = self._renderer, None
        if r is None:
            return
        plat = getattr(r, "_platform", None)
        try:
            plat.make_current()
            r._renderer.delete()
        finally:
            display = getattr(plat, "_egl_display", None)
            context = getattr(plat, "_egl_context", None)
            if display is not None and context is not None:
                from OpenGL import EGL

                EGL.eglMakeCurrent(display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE,
                                   EGL.EGL_NO_CONTEXT)
                EGL.eglDestroyContext(display, context)
                plat._egl_context = None
                plat._egl_display = None
            elif plat is not None:
                plat.delete_context()
            r._platform = None           # pyrender's __del__ then does nothing

    def __del__(self):
        try:
            self.close()
        except Exception:  # noqa: BLE001 - best effort at interpreter shutdown
            pass

    # ------------------------------------------------------------------ scene content

    def _set_sheet(self, texture_rgb: np.ndarray, extent_mm, height_grid=None) -> float:
        tex = np.asarray(texture_rgb)
        if tex.ndim != 3 or tex.shape[2] != 3 or tex.dtype != np.uint8:
            raise VisionCalError(f"expected an (H, W, 3) uint8 texture, got {tex.shape} "
                                 f"{tex.dtype}", field="texture_rgb")
        if max(tex.shape[:2]) > self.max_texture_px:
            raise VisionCalError(f"texture {tex.shape[1]}x{tex.shape[0]} exceeds the OpenGL "
                                 f"limit of {self.max_texture_px} px; lower px_per_mm",
                                 field="texture_rgb")
        ext = tuple(float(v) for v in extent_mm)
        tex = np.ascontiguousarray(tex)
        hkey = None
        if height_grid is not None:
            xs, ys, Z = (np.ascontiguousarray(a, dtype=np.float64) for a in height_grid)
            hkey = zlib.crc32(xs.tobytes() + ys.tobytes() + Z.tobytes())
        key = (tex.shape, ext, zlib.crc32(tex.data), hkey)
        if key == self._sheet_key:
            return 0.0
        t0 = time.perf_counter()
        if self._sheet_key is not None and self._sheet_key[0] == key[0] \
                and self._sheet_key[1:4:2] == key[1:4:2] and self._patch_sheet(tex):
            self._sheet_key = key
            return time.perf_counter() - t0
        if self._sheet_node is not None:
            self._scene.remove_node(self._sheet_node)
        x0, y0, x1, y1 = ext
        pos = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0]], dtype=np.float32)
        uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=np.float32)
        sampler = pyrender.Sampler(magFilter=pyrender.GLTF.LINEAR,
                                   minFilter=_MIN_FILTER,
                                   wrapS=pyrender.GLTF.CLAMP_TO_EDGE,
                                   wrapT=pyrender.GLTF.CLAMP_TO_EDGE)
        texture = _BiasedTexture(source=tex.copy(), source_channels="RGB", sampler=sampler,
                                 lod_bias=self.lod_bias)
        mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0],
                                                 baseColorTexture=texture, doubleSided=True)
        if height_grid is None:
            prim = pyrender.Primitive(positions=pos,
                                      normals=np.tile([0, 0, 1], (4, 1)).astype(np.float32),
                                      texcoord_0=uv, indices=np.array([[0, 1, 2], [0, 2, 3]]),
                                      material=mat)
        else:  # a paper that is not flat: a fine mesh raised by its height field
            pos, uv, idx = _height_mesh(xs, ys, Z, ext)
            prim = pyrender.Primitive(positions=pos,
                                      normals=np.tile([0, 0, 1], (len(pos), 1)).astype(np.float32),
                                      texcoord_0=uv, indices=idx, material=mat)
        self._sheet_node = self._scene.add(pyrender.Mesh([prim]))
        self._sheet_texture = texture
        self._sheet_key = key
        return time.perf_counter() - t0

    def _patch_sheet(self, tex: np.ndarray) -> bool:
        """Upload only the rectangle where ``tex`` differs from the sheet texture in the
        OpenGL context, then rebuild its mipmaps from the whole base level (what a fresh
        upload does, so the same texels at every level: a series photo adds one mark's
        few texels to a 4752 x 3360 texture). False: not uploaded yet, nothing done."""
        texture = self._sheet_texture
        if texture is None or texture._texid is None or texture.source.shape != tex.shape:
            return False
        old = texture.source
        rows = np.flatnonzero(np.any(old != tex, axis=(1, 2)))
        if rows.size:
            r0, r1 = int(rows[0]), int(rows[-1]) + 1
            cols = np.flatnonzero(np.any(old[r0:r1] != tex[r0:r1], axis=(0, 2)))
            c0, c1 = int(cols[0]), int(cols[-1]) + 1
            old[r0:r1, c0:c1] = tex[r0:r1, c0:c1]
            from OpenGL import GL

            self._renderer._platform.make_current()
            H = tex.shape[0]
            data = np.ascontiguousarray(np.flip(tex[r0:r1, c0:c1], axis=0))
            GL.glBindTexture(GL.GL_TEXTURE_2D, texture._texid)
            GL.glTexSubImage2D(GL.GL_TEXTURE_2D, 0, c0, H - r1, c1 - c0, r1 - r0, GL.GL_RGB,
                               GL.GL_UNSIGNED_BYTE, data)
            GL.glGenerateMipmap(GL.GL_TEXTURE_2D)
            GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        return True

    def _set_arm(self, arm, lights) -> list:
        """Add the arm meshes (baked lighting); returns shadow casters [(points (n,3), top)]."""
        if self._arm_node is not None:
            self._scene.remove_node(self._arm_node)
            self._arm_node = None
        if not arm:
            return []
        light_list = _lights(lights)
        meshes, casters = [], []
        for i, link in enumerate(arm):
            try:
                p0, p1, width, top = link
                p0, p1 = np.asarray(p0, float).reshape(2), np.asarray(p1, float).reshape(2)
                width, top = float(width), float(top)
            except (TypeError, ValueError) as e:
                raise VisionCalError("expected (p0_xy_mm, p1_xy_mm, width_mm, height_mm), "
                                     f"got {link!r}", field=f"arm[{i}]") from e
            thick = min(0.5 * width, 0.8 * top)
            if top <= 0 or width <= 0:
                raise VisionCalError("expected positive width and height", field=f"arm[{i}]")
            d = p1 - p0
            length = float(np.hypot(*d)) + width          # rounded-ish ends overlap
            ang = float(np.arctan2(d[1], d[0]))
            box = trimesh.creation.box(extents=(length, width, thick))
            T = np.eye(4)
            T[:3, :3] = trimesh.transformations.rotation_matrix(ang, [0, 0, 1])[:3, :3]
            T[:2, 3] = (p0 + p1) / 2
            T[2, 3] = top - thick / 2
            box.apply_transform(T)
            meshes.append(_baked(box, ARM_RGB, light_list))
            casters.append((np.asarray(box.vertices), top - thick))
        # pen holder: a vertical cylinder at the end of the last link, down to near the paper
        p0, p1, width, top = arm[-1]
        p1 = np.asarray(p1, float).reshape(2)
        r = 0.3 * float(width)
        zb = 3.0
        zt = float(top) - 0.25 * width          # the cap ends inside the link box
        cyl = trimesh.creation.cylinder(radius=r, height=zt - zb, sections=40)
        cyl.apply_translation([p1[0], p1[1], (zb + zt) / 2])
        meshes.append(_baked(cyl, HOLDER_RGB, light_list))
        casters.append((np.asarray(cyl.vertices), zb))
        self._arm_node = self._scene.add(pyrender.Mesh(meshes))
        return casters

    # ------------------------------------------------------------------ rendering

    def render(self, texture_rgb, *, extent_mm, T_cam_sheet, arm=None,
               lights="default", height_grid=None) -> np.ndarray:
        """Ideal pinhole image (h, w, 3) uint8 of the textured sheet (and the arm)."""
        return self._shoot(texture_rgb, extent_mm=extent_mm, T_cam_sheet=T_cam_sheet, arm=arm,
                           lights=lights, lens=None, height_grid=height_grid)

    def _shoot(self, texture_rgb, *, extent_mm, T_cam_sheet, arm, lights, lens,
               height_grid=None):
        """Render at the supersampled size, apply ``lens`` = (K_out, dist) there, area-average."""
        t0 = time.perf_counter()
        upload = self._set_sheet(texture_rgb, extent_mm, height_grid)
        casters = self._set_arm(arm, lights)
        T = np.asarray(T_cam_sheet, dtype=float)
        pose = np.linalg.inv(T) @ np.diag([1.0, -1.0, -1.0, 1.0])
        self._scene.set_pose(self._cam_node, pose)
        t1 = time.perf_counter()
        shadows = bool(casters) and lights not in (None, "none")
        inner = getattr(self._renderer, "_renderer", None)
        if inner is None or not hasattr(inner, "_read_main_framebuffer") \
                or sys.platform == "darwin":
            color, depth = self._renderer.render(self._scene, flags=pyrender.RenderFlags.FLAT)
        else:   # the colour only: the shadows read the depth of their own window
            inner._read_main_framebuffer = functools.partial(_read_color_only, inner)
            try:
                rgba, depth = self._renderer.render(self._scene,
                                                    flags=pyrender.RenderFlags.FLAT)
            finally:
                del inner._read_main_framebuffer
            if not shadows and lens is None:
                # the s x s area average of whole blocks commutes with the flip; the alpha
                # channel is averaged on its own and dropped
                t2 = time.perf_counter()
                img = rgba if self.supersample == 1 else cv2.resize(
                    rgba, self.size_px, interpolation=cv2.INTER_AREA)
                img = np.ascontiguousarray(np.flip(img, axis=0)[..., :3])
                t5 = time.perf_counter()
                self.last_timing = {"texture_upload_s": upload, "render_s": t2 - t1,
                                    "downsample_s": t5 - t2, "post_s": 0.0,
                                    "total_s": t5 - t0}
                return img
            color = np.ascontiguousarray(np.flip(rgba, axis=0)[..., :3])
        t2 = time.perf_counter()
        s = self.supersample
        w, h = self.size_px
        if shadows:
            color = self._shadowed(color, depth, casters, T, lights)
        t3 = time.perf_counter()
        if lens is not None:
            K_out, dist = lens
            color = distort_image(color, K=self._supersampled(K_out), dist=dist,
                                  K_ideal=self.K_render,
                                  interpolation=LENS_INTERPOLATION)
        t4 = time.perf_counter()
        img = color if s == 1 else cv2.resize(color, (w, h), interpolation=cv2.INTER_AREA)
        t5 = time.perf_counter()
        self.last_timing = {"texture_upload_s": upload, "render_s": t2 - t1,
                            "downsample_s": (t3 - t2) + (t5 - t4), "post_s": t4 - t3,
                            "total_s": t5 - t0}
        return np.ascontiguousarray(img)

    def _supersampled(self, K) -> np.ndarray:
        """The camera matrix of the supersampled image for an output camera matrix K."""
        s = self.supersample
        Ks = np.array(K, dtype=float)
        Ks[:2, :] *= s
        Ks[:2, 2] += (s - 1) / 2
        return Ks

    def _shadowed(self, color, depth, casters, T, lights):
        """Multiply soft arm shadows onto the sheet pixels of a (supersampled) render.

        Shadows are drawn and blurred at 1/``SHADOW_SCALE`` resolution (they are soft) and
        applied where the depth buffer shows the paper plane (not the arm, not the table).
        Only the window where the shadow can change a pixel is worked at full resolution
        (:func:`_shadow_window`); ``depth`` None: its depth is read back from the render
        (:func:`_read_depth_window`), the same values as pyrender's whole depth image there.
        """
        key_dir = _unit(_lights(lights)[0][0])
        Ks = self.K_render
        hs, ws = color.shape[:2]
        q = SHADOW_SCALE
        hq, wq = -(-hs // q), -(-ws // q)
        Kq = Ks.copy()
        Kq[:2, :] /= q
        Kq[:2, 2] += 0.5 / q - 0.5          # pixel centres of the small grid
        mask = np.zeros((hq, wq), np.float32)
        R, t = T[:3, :3], T[:3, 3]
        shift = 4
        for pts, z_low in casters:
            k = -pts[:, 2] / key_dir[2]                 # along the light down to z = 0
            foot = pts[:, :2] + k[:, None] * key_dir[:2]
            hull = cv2.convexHull(foot.astype(np.float32)).reshape(-1, 2)
            pc = np.column_stack([hull, np.zeros(len(hull))]) @ R.T + t
            if np.any(pc[:, 2] <= 0):
                continue
            uv = pc[:, :2] / pc[:, 2:3] @ Kq[:2, :2].T + Kq[:2, 2]
            one = np.zeros_like(mask)
            cv2.fillConvexPoly(one, np.round(uv * (1 << shift)).astype(np.int32), 1.0,
                               lineType=cv2.LINE_AA, shift=shift)
            # the penumbra grows with the height of the caster
            sigma = max(0.7, 0.08 * z_low * Kq[0, 0] / float(np.mean(pc[:, 2])))
            one = cv2.GaussianBlur(one, (0, 0), sigma)
            np.maximum(mask, one, out=mask)
        win = _shadow_window(mask, hs, ws, q)
        if win is None:
            return color
        (r0, r1, c0, c1), mask = win
        if depth is None:
            depth = _read_depth_window(self._renderer._renderer, r0, r1, c0, c1,
                                       self._camera.znear, self._camera.zfar)
        else:
            depth = depth[r0:r1, c0:c1]
        # sheet pixels only: the depth buffer equals the depth of the paper plane there
        n = R[:, 2]
        a = (n[0] / Ks[0, 0]) * (np.arange(ws, dtype=np.float32) - Ks[0, 2])
        b = (n[1] / Ks[1, 1]) * (np.arange(hs, dtype=np.float32) - Ks[1, 2])
        with np.errstate(divide="ignore", invalid="ignore"):
            z_plane = np.float32(n @ t) / (a[None, c0:c1] + b[r0:r1, None] + np.float32(n[2]))
        off_sheet = np.abs(depth - z_plane) > 1.0 + 1e-3 * np.abs(z_plane)
        mask[off_sheet] = 0.0
        gain = 1.0 - SHADOW_STRENGTH * mask
        out = color.copy()
        out[r0:r1, c0:c1] = np.clip(np.rint(color[r0:r1, c0:c1].astype(np.float32)
                                            * gain[..., None]), 0, 255)
        return out

    def photograph(self, texture_rgb, *, extent_mm, T_cam_sheet, dist=None, K_dist=None,
                   arm=None, lights="default", vignetting: float = 0.0,
                   noise_sigma: float = 0.0, jpeg_quality=None, rng=None,
                   height_grid=None) -> np.ndarray:
        """A photo (h, w, 3) uint8: render, lens distortion, vignetting, noise, JPEG.

        The lens is ``(K_dist or K, dist)``: a sheet point lands where
        ``cv2.projectPoints(..., K_dist, dist)`` puts it. The lens is applied to the
        supersampled render before it is averaged down (``distort_image`` with bilinear
        cv2.remap there, ~10x faster than the B-spline path; the dot-centre figures come
        from ``bench/render.py --accuracy``); the lens maps are built once per (K, dist) and
        cached. Parts of the distorted frame that
        fall outside the ideal render come out black (barrel distortion, k1 < 0, in the
        corners): build the Photographer with a shorter focal length to avoid that.
        ``height_grid`` = (xs (nx,), ys (ny,), Z (ny, nx)) mm: the paper is not flat; the
        texel of sheet point (x, y) is drawn at (x, y, h) (bilinear mesh over the grid,
        see :mod:`vision_cal.world.height`).
        """
        rng = np.random.default_rng(rng)
        lens = None
        if dist is not None or K_dist is not None:
            lens = (self.K if K_dist is None else np.asarray(K_dist, dtype=float), dist)
        img = self._shoot(texture_rgb, extent_mm=extent_mm, T_cam_sheet=T_cam_sheet, arm=arm,
                          lights=lights, lens=lens, height_grid=height_grid)
        timing = dict(self.last_timing)
        t0 = time.perf_counter()
        K_out = self.K if K_dist is None else np.asarray(K_dist, dtype=float)
        h, w = img.shape[:2]
        if vignetting or noise_sigma:
            out = img.astype(np.float32)
            if vignetting:
                out *= _vignetting_gain((w, h), K_out, float(vignetting))[..., None]
            if noise_sigma:
                # noise_sigma * sqrt(0.25 + 0.75 * clip(out) / 255), in place (the same
                # float32 operations in the same order, without six image-sized temporaries)
                std = np.clip(out, 0, 255)
                std *= 0.75
                std /= 255.0
                std += 0.25
                np.sqrt(std, out=std)
                std *= float(noise_sigma)
                noise = rng.standard_normal(out.shape, dtype=np.float32)
                noise *= std
                out += noise
                del std, noise
            np.rint(out, out=out)
            img = np.clip(out, 0, 255, out=out).astype(np.uint8)
        if jpeg_quality is not None:
            ok, buf = cv2.imencode(".jpg", cv2.cvtColor(img, cv2.COLOR_RGB2BGR),
                                   [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
            if not ok:
                raise VisionCalError("JPEG encoding failed", field="jpeg_quality")
            img = cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        post = time.perf_counter() - t0
        timing["post_s"] += post
        timing["total_s"] += post
        self.last_timing = timing
        return img


def _height_mesh(xs, ys, Z, extent_mm):
    """Vertices (N, 3), texture coords (N, 2) and triangles (M, 3) of the raised paper.

    Vertex (x, y, h) carries the texture coordinate of the flat quad at (x, y): the
    printed point (x, y) is lifted straight up (the sheet frame keeps its xy).
    """
    x0, y0, x1, y1 = extent_mm
    X, Y = np.meshgrid(xs, ys)
    pos = np.column_stack([X.ravel(), Y.ravel(), np.asarray(Z).ravel()]).astype(np.float32)
    uv = np.column_stack([(X.ravel() - x0) / (x1 - x0),
                          (Y.ravel() - y0) / (y1 - y0)]).astype(np.float32)
    nx, ny = len(xs), len(ys)
    i = np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None, :]
    i = i.ravel()
    idx = np.concatenate([np.column_stack([i, i + 1, i + nx + 1]),
                          np.column_stack([i, i + nx + 1, i + nx])]).astype(np.uint32)
    return pos, uv, idx


def _vignetting_gain(size_px, K, strength: float) -> np.ndarray:
    K = np.ascontiguousarray(K, dtype=np.float64)
    return _vignetting_gain_cached((int(size_px[0]), int(size_px[1])), K.tobytes(),
                                   float(strength))


@functools.lru_cache(maxsize=4)
def _vignetting_gain_cached(size_px, K_key: bytes, strength: float) -> np.ndarray:
    K = np.frombuffer(K_key).reshape(3, 3)
    w, h = size_px
    u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    x = (u - K[0, 2]) / K[0, 0]
    y = (v - K[1, 2]) / K[1, 1]
    cos4 = 1.0 / (1.0 + x * x + y * y) ** 2
    xc = max(abs(-K[0, 2]), abs(w - 1 - K[0, 2])) / K[0, 0]
    yc = max(abs(-K[1, 2]), abs(h - 1 - K[1, 2])) / K[1, 1]
    cos4_corner = 1.0 / (1.0 + xc * xc + yc * yc) ** 2
    return (1.0 - strength * (1.0 - cos4) / (1.0 - cos4_corner)).astype(np.float32)


def _lights(lights):
    if lights in (None, "none"):
        return [((0.0, 0.0, -1.0), 0.7)]
    if lights == "default":
        return list(DEFAULT_LIGHTS)
    try:
        return [(tuple(float(c) for c in d), float(i)) for d, i in lights]
    except (TypeError, ValueError) as e:
        raise VisionCalError("expected 'default', None or [(direction_xyz, intensity)]",
                             field="lights") from e


def _baked(mesh: trimesh.Trimesh, albedo, light_list) -> pyrender.Primitive:
    """A pyrender primitive with per-face lighting baked into vertex colours (FLAT pass)."""
    m = mesh.copy()
    m.unmerge_vertices()
    n = np.asarray(m.face_normals)                       # (F, 3)
    shade = np.full(len(n), AMBIENT)
    for d, inten in light_list:
        to_light = -_unit(d)
        lam = np.clip(n @ to_light, 0.0, None)
        # a little specular for a vertical viewer: Blinn half-vector with straight up
        half = _unit(to_light + np.array([0.0, 0.0, 1.0]))
        spec = np.clip(n @ half, 0.0, None) ** 40
        shade = shade + inten * lam + 0.25 * inten * spec
    rgb = np.clip(np.asarray(albedo)[None, :] * shade[:, None], 0.0, 1.0)
    colors = np.repeat(rgb, 3, axis=0)                   # faces were unmerged: 3 verts each
    verts = np.asarray(m.vertices, dtype=np.float32)
    faces = np.asarray(m.faces)
    col = np.zeros((len(verts), 4), np.float32)
    col[faces.ravel()] = np.column_stack([colors, np.ones(len(colors))])
    mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0],
                                             doubleSided=True)
    return pyrender.Primitive(positions=verts, color_0=col, indices=faces, material=mat)

// view_check.h - does the camera see the tissue at all? A set-up check for a video of the
// background alone: a camera whose eye is inside the tissue (its surface is drawn from
// outside only: the back faces are culled) or whose view holds none of it (pointed away, or
// too close to an edge) gives frames without tissue, silently (measured: `esim run
// scenarios/slab_cut.yaml --set camera.eye_m=[0,0,0.005] --set camera.target_m=[0.01,0,0.005]`
// wrote 120 frames of the background gradient and no warning).
// Also: is a point (the tool) hidden behind the surface? A camera that looks at the cut
// from below or through the tissue's side shows no tool.
// Pure geometry in double precision, no GL: the camera of RenderOptions (eye, target, up,
// vertical field of view, the frame's aspect) against the snapshot's surface.
#pragma once

#include <array>

#include "render/renderer.h"
#include "sim/snapshot.h"

namespace esim {

struct ViewCheck {
  bool eyeInside = false;    // the eye inside the closed surface (parity of a ray's crossings)
  bool seesSurface = false;  // a surface vertex in the view, or a ray through the view's centre
                             // or one of its corners hits a triangle
  int verticesInView = 0;    // surface vertices inside the view (in front of the eye)
};

ViewCheck checkView(const RenderOptions& o, const SurfaceSnapshot& snap);

// is the point p [m] inside the camera's view (in front of the eye, within its field of view;
// not whether something hides it)?
bool inView(const RenderOptions& o, const std::array<double, 3>& p);

// is the point p [m] hidden from the eye by the surface (a triangle crossed on the segment
// between them, short of p)?
bool hiddenBySurface(const RenderOptions& o, const SurfaceSnapshot& snap,
                     const std::array<double, 3>& p);

}  // namespace esim

// Primary-ray generation from a scene Camera (RenderMan conventions: left-handed camera space
// looking down +z, screen window on the plane z = 1 scaled by the field of view). Used by the
// integrator (render.*) and tests; depends only on scene.h and accel.h (for Ray).
#pragma once

#include "renderer/accel.h"
#include "renderer/scene.h"

namespace relief {

class CameraRays {
 public:
  // `width` x `height` is the raster the rays are generated for (it may differ from Format when
  // the command line overrides the resolution; the default screen window follows it).
  CameraRays(const Camera& camera, int width, int height);

  // The ray through raster position (x, y): x right, y down, pixel (i, j) covers [i, i+1) x
  // [j, j+1). For perspective, t measures camera-space depth, so tMin/tMax are the clipping planes.
  Ray generate(float rasterX, float rasterY) const;

  // The screen window actually used: left, right, bottom, top.
  const float* screenWindow() const { return window_; }

 private:
  glm::mat4 worldFromCamera_;
  glm::mat4 projectedFromScreen_;  // inverse of Camera::screenFromProjected
  bool screenTransformed_;
  glm::vec3 originWorld_;
  bool perspective_;
  float tanHalfFov_;
  float window_[4];
  float width_, height_;
  float nearClip_, farClip_;
};

}  // namespace relief

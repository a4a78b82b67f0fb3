// Primary-ray generation (see camera.h).
#include "renderer/camera.h"

#include <algorithm>
#include <cmath>

namespace relief {

CameraRays::CameraRays(const Camera& camera, int width, int height)
    : worldFromCamera_(camera.worldFromCamera),
      projectedFromScreen_(glm::inverse(camera.screenFromProjected)),
      screenTransformed_(camera.screenFromProjected != glm::mat4(1.0f)),
      originWorld_(camera.worldFromCamera * glm::vec4(0, 0, 0, 1)),
      perspective_(camera.perspective),
      tanHalfFov_(std::tan(glm::radians(camera.fovDegrees) * 0.5f)),
      width_(float(std::max(width, 1))),
      height_(float(std::max(height, 1))),
      nearClip_(camera.nearClip),
      farClip_(camera.farClip) {
  if (camera.screenWindowSet) {
    std::copy(camera.screenWindow, camera.screenWindow + 4, window_);
  } else {
    // RenderMan's default: [-1, 1] along the shorter image axis, the aspect ratio along the other.
    const float aspect = width_ * camera.pixelAspect / height_;
    if (aspect >= 1.0f) {
      window_[0] = -aspect, window_[1] = aspect, window_[2] = -1.0f, window_[3] = 1.0f;
    } else {
      window_[0] = -1.0f, window_[1] = 1.0f, window_[2] = -1.0f / aspect, window_[3] = 1.0f / aspect;
    }
  }
}

Ray CameraRays::generate(float rasterX, float rasterY) const {
  float sx = window_[0] + (window_[1] - window_[0]) * (rasterX / width_);
  float sy = window_[3] - (window_[3] - window_[2]) * (rasterY / height_);
  if (screenTransformed_) {
    const glm::vec4 q = projectedFromScreen_ * glm::vec4(sx, sy, 0.0f, 1.0f);
    if (q.w != 0.0f) sx = q.x / q.w, sy = q.y / q.w;
  }
  Ray ray;
  if (perspective_) {
    ray.origin = originWorld_;
    // z stays 1 so that t is camera-space depth and the clipping planes apply directly.
    ray.direction = glm::vec3(worldFromCamera_ * glm::vec4(sx * tanHalfFov_, sy * tanHalfFov_, 1, 0));
    ray.tMin = nearClip_;
  } else {
    ray.origin = glm::vec3(worldFromCamera_ * glm::vec4(sx, sy, 0, 1));
    ray.direction = glm::vec3(worldFromCamera_ * glm::vec4(0, 0, 1, 0));
    ray.tMin = nearClip_;
  }
  ray.tMax = farClip_;
  return ray;
}

}  // namespace relief

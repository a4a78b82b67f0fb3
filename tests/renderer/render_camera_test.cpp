// Tests of primary-ray generation: RenderMan's field of view across the shorter axis, the
// left-handed camera looking down +z, raster y pointing down, and orthographic rays.
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include "renderer/camera.h"

namespace relief {
namespace {

TEST(RenderCamera, CentreRayLooksDownPlusZ) {
  Camera cam;
  cam.fovDegrees = 60;
  CameraRays rays(cam, 64, 48);
  const Ray r = rays.generate(32, 24);
  EXPECT_FLOAT_EQ(r.direction.x, 0.0f);
  EXPECT_FLOAT_EQ(r.direction.y, 0.0f);
  EXPECT_FLOAT_EQ(r.direction.z, 1.0f);
  EXPECT_EQ(r.origin, glm::vec3(0));
}

TEST(RenderCamera, FovSpansTheShorterAxis) {
  Camera cam;
  cam.fovDegrees = 60;
  const float t = std::tan(glm::radians(30.0f));
  {
    CameraRays wide(cam, 200, 100);  // landscape: fov is vertical
    const Ray top = wide.generate(100, 0);
    EXPECT_NEAR(top.direction.y / top.direction.z, t, 1e-6f);  // raster y = 0 is the top
    const Ray right = wide.generate(200, 50);
    EXPECT_NEAR(right.direction.x / right.direction.z, 2 * t, 1e-6f);
  }
  {
    CameraRays tall(cam, 100, 200);  // portrait: fov is horizontal
    const Ray right = tall.generate(100, 100);
    EXPECT_NEAR(right.direction.x / right.direction.z, t, 1e-6f);
    const Ray bottom = tall.generate(50, 200);
    EXPECT_NEAR(bottom.direction.y / bottom.direction.z, -2 * t, 1e-6f);
  }
}

TEST(RenderCamera, ScreenWindowOverridesTheAspectDefault) {
  Camera cam;
  cam.perspective = false;
  cam.screenWindowSet = true;
  const float sw[4] = {0, 4, -1, 1};
  std::copy(sw, sw + 4, cam.screenWindow);
  CameraRays rays(cam, 10, 10);
  const Ray r = rays.generate(10, 10);  // bottom-right corner
  EXPECT_FLOAT_EQ(r.origin.x, 4.0f);
  EXPECT_FLOAT_EQ(r.origin.y, -1.0f);
  EXPECT_EQ(r.direction, glm::vec3(0, 0, 1));
}

TEST(RenderCamera, OrthographicDefaultWindowFollowsTheAspect) {
  Camera cam;  // what the RIB reader gives a scene with no Projection
  cam.perspective = false;
  cam.worldFromCamera = glm::inverse(glm::translate(glm::mat4(1.0f), glm::vec3(0, 0, 5)));
  CameraRays rays(cam, 200, 100);  // landscape: [-2, 2] x [-1, 1]
  EXPECT_FLOAT_EQ(rays.screenWindow()[0], -2.0f);
  EXPECT_FLOAT_EQ(rays.screenWindow()[3], 1.0f);
  const Ray topLeft = rays.generate(0, 0), centre = rays.generate(100, 50);
  EXPECT_EQ(topLeft.origin, glm::vec3(-2, 1, -5));
  EXPECT_EQ(centre.origin, glm::vec3(0, 0, -5));
  EXPECT_EQ(topLeft.direction, centre.direction);  // parallel rays
  EXPECT_EQ(centre.direction, glm::vec3(0, 0, 1));
}

TEST(RenderCamera, WorldFromCameraMovesAndTurnsRays) {
  Camera cam;
  // Camera at (0, 0, -5) looking down world +z: cameraFromWorld translates by +5.
  cam.worldFromCamera = glm::inverse(glm::translate(glm::mat4(1.0f), glm::vec3(0, 0, 5)));
  cam.nearClip = 0.5f;
  cam.farClip = 50.0f;
  CameraRays rays(cam, 8, 8);
  const Ray r = rays.generate(4, 4);
  EXPECT_EQ(r.origin, glm::vec3(0, 0, -5));
  EXPECT_FLOAT_EQ(r.tMin, 0.5f);
  EXPECT_FLOAT_EQ(r.tMax, 50.0f);
  // t is camera depth: the point at t = 5 is the world origin.
  const glm::vec3 p = r.origin + 5.0f * r.direction;
  EXPECT_NEAR(glm::length(p), 0.0f, 1e-6f);
}

}  // namespace
}  // namespace relief

// Synthetic stereo scenes with exact ground truth: a rectified pinhole stereo rig, a textured
// box room around it and textured objects (spheres, boxes, flat cards) moving rigidly.
//
// Coordinates: camera coordinates of the LEFT camera, OpenCV axes (x right, y down, z forward),
// in scene units. The right camera sits at (baseline, 0, 0) with the same orientation. A pixel
// (col, row) has its centre at integer coordinates and looks along ((col-cx)/f, (row-cy)/f, 1).
// The rig is static in these coordinates: ego-motion appears as the inverse rigid motion of every
// static surface (the room, which is itself a rigid object, and with kRobot the static objects).
//
// Every object (the room is object 0) has one pose per frame, frames 0..frames (one more than
// the rendered frames, so the ground truth "into the future" of the last frame is defined).
// A surface point p (object-local) is at poses[t].ToCamera(p) at frame t.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "sfrt/status.h"
#include "synth/geometry.h"
#include "synth/texture.h"

namespace sfrt::synth {

struct Camera {
  double focal = 1050;  // px
  double baseline = 1;  // scene units; the right camera is at (+baseline, 0, 0)
  double cx = 479.5;    // px
  double cy = 269.5;    // px
  int width = 960;
  int height = 540;
};

enum class ShapeKind { kRoom, kSphere, kBox, kCard };

struct SceneObject {
  ShapeKind kind = ShapeKind::kSphere;
  // Room and box: half extents along local x, y, z. Sphere: radius in x. Card: the flat
  // rectangle |x| <= x, |y| <= y in the local plane z = 0, visible from both sides.
  Vec3 size;
  int texture = 0;           // index into Scene::textures
  double texel_size = 0.05;  // scene units per texel
  double gain = 1.0;         // brightness factor
  std::vector<Pose> poses;   // one per frame, frames + 1 entries
};

struct Scene {
  Camera camera;
  int frames = 0;  // rendered frames; poses hold frames + 1 entries
  std::vector<SceneObject> objects;
  std::vector<std::shared_ptr<const Texture>> textures;
  Vec3 light;            // unit vector towards the light (camera coordinates)
  double ambient = 0.4;  // shade = ambient + (1 - ambient) * max(0, n . light)
};

struct Hit {
  int object = -1;
  double depth = 0;     // ray parameter; equals the camera-space Z for rays with direction z = 1
  Vec3 local;           // hit point, object-local
  Vec3 local_normal;    // unit surface normal, object-local, facing the ray
  double u = 0, v = 0;  // texture coordinates in scene units
};

// Nearest surface hit at frame `frame` along origin + s * dir, s > 0. False if nothing is hit
// (cannot happen for a camera inside the room).
bool CastRay(const Scene& scene, int frame, Vec3 origin, Vec3 dir, Hit* hit);

// Colour (BGR, about [0, 1]) of a hit at frame `frame`.
void Shade(const Scene& scene, int frame, const Hit& hit, float bgr[3]);

// Where the surface point seen at camera position `x` on `object` at frame t is at frame t+1.
inline Vec3 MovePoint(const SceneObject& object, int t, Vec3 x) {
  return object.poses[t + 1].ToCamera(object.poses[t].ToLocal(x));
}

// Supplies textures: procedural, or images from a folder (loaded once and cached).
class TextureSource {
 public:
  TextureSource() = default;  // procedural textures
  explicit TextureSource(std::vector<std::string> files) : files_(std::move(files)) {}
  Result<std::shared_ptr<const Texture>> Next(Rng& rng);

 private:
  std::vector<std::string> files_;
  std::map<std::string, std::shared_ptr<const Texture>> cache_;
};

// Scene families. kRoom: the rig is static inside a box room whose small motion stands in for
// ego-motion, sizes relative to f*B (scale-free). kRobot: metric (metres), for a robot's stereo
// rig (e.g. baseline 0.12 m): a room of a few metres, the rig driving through it (forward speed,
// yaw and small pitch/roll rates, so every static surface moves by the inverse ego-motion) and
// objects of 0.1-0.5 m at 0.8-5 m, some static, most moving on their own.
enum class ScenePreset { kRoom, kRobot };

struct SceneOptions {
  Camera camera;
  ScenePreset preset = ScenePreset::kRoom;
  int frames = 10;  // frames to render (poses are made for frames + 1)
  int objects = 8;  // moving objects besides the room
  // kRobot: the largest pitch rate of the rig, radians per frame (drawn uniformly in +-this per
  // sequence). The default 0.004 moves the image by at most f * 0.004 px a frame: a third of a
  // pixel at f = 90 px, too little to learn vertical ego-motion from; a larger range shows it.
  double max_pitch_rate = 0.004;
  // kRobot: the largest forward speed, scene units per frame. 15% of the sequences creep at
  // up to 0.01, the others drive at 0.01 to this (at most 0.01 when this is below it).
  double max_speed = 0.10;
};

// A random scene for sequence `sequence` of the data set seeded with `seed`. Deterministic:
// the same arguments (and texture files) give the same scene on every machine.
Result<Scene> MakeRandomScene(const SceneOptions& options, uint64_t seed, int sequence,
                              TextureSource& textures);

}  // namespace sfrt::synth

#include "synth/scene.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sfrt::synth {
namespace {

constexpr double kEps = 1e-9;

// Unit vector uniformly on the sphere (rejection from the unit ball; no trigonometry).
Vec3 RandomDirection(Rng& rng) {
  for (;;) {
    Vec3 v{rng.Uniform(-1, 1), rng.Uniform(-1, 1), rng.Uniform(-1, 1)};
    const double n2 = Dot(v, v);
    if (n2 > 1e-4 && n2 <= 1.0) return (1.0 / std::sqrt(n2)) * v;
  }
}

// Uniformly random orientation (rejection from the 4-ball).
Quat RandomOrientation(Rng& rng) {
  for (;;) {
    Quat q{rng.Uniform(-1, 1), rng.Uniform(-1, 1), rng.Uniform(-1, 1), rng.Uniform(-1, 1)};
    const double n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
    if (n2 > 1e-4 && n2 <= 1.0) return Normalized(q);
  }
}

// Rotation by an angle theta about a random axis, given s = sin(theta / 2).
Quat SmallRotation(Rng& rng, double s) {
  const Vec3 axis = RandomDirection(rng);
  return Quat{std::sqrt(1.0 - s * s), s * axis.x, s * axis.y, s * axis.z};
}

Quat Conjugate(Quat q) { return {q.w, -q.x, -q.y, -q.z}; }

// Limits within which an object's centre moves; velocity components reflect at the walls.
struct Bounds {
  double z_min = 0, z_max = 0;
  double x_slope = 0, y_slope = 0;  // |x| <= x_slope * z, |y| <= y_slope * z
  double x_abs = -1, y_abs = -1;    // if >= 0: |x| <= x_abs, |y| <= y_abs, |z| <= z_max (room)
};

bool Inside(const Bounds& b, Vec3 t, int axis) {
  if (b.x_abs >= 0) {
    if (axis == 0) return std::fabs(t.x) <= b.x_abs;
    if (axis == 1) return std::fabs(t.y) <= b.y_abs;
    return std::fabs(t.z) <= b.z_max;
  }
  if (axis == 2) return t.z >= b.z_min && t.z <= b.z_max;
  if (axis == 0) return std::fabs(t.x) <= b.x_slope * t.z;
  return std::fabs(t.y) <= b.y_slope * t.z;
}

// Poses for frames 0..count-1: constant velocity and spin, reflecting translation at the bounds
// and (if max_half_angle_sin > 0) reversing the spin when the net rotation exceeds the limit.
std::vector<Pose> MakePoses(Vec3 t0, Quat q0, Vec3 velocity, Quat spin, const Bounds& bounds,
                            double min_w, int count) {
  std::vector<Pose> poses;
  poses.reserve(static_cast<size_t>(count));
  Vec3 t = t0;
  Quat q = q0;
  Quat net;  // rotation applied since frame 0 (for the room's limit)
  for (int i = 0; i < count; ++i) {
    poses.push_back(Pose{ToMatrix(q), t});
    Vec3 next = t + velocity;
    // Reflect: z first (the x/y limits depend on z for objects).
    if (!Inside(bounds, next, 2) && Inside(bounds, t, 2)) {
      velocity.z = -velocity.z;
      next = t + velocity;
    }
    if (!Inside(bounds, next, 0) && Inside(bounds, t, 0)) {
      velocity.x = -velocity.x;
      next = t + velocity;
    }
    if (!Inside(bounds, next, 1) && Inside(bounds, t, 1)) {
      velocity.y = -velocity.y;
      next = t + velocity;
    }
    t = next;
    Quat next_net = Normalized(spin * net);
    if (min_w > 0 && std::fabs(next_net.w) < min_w) {
      spin = Conjugate(spin);
      next_net = Normalized(spin * net);
    }
    net = next_net;
    q = Normalized(spin * q);
  }
  return poses;
}

// Ray parameter interval [s_near, s_far] where the ray is inside the box |p_i| <= h_i, with the
// axes at which it enters and leaves. False if it misses.
bool SlabInterval(Vec3 o, Vec3 d, Vec3 h, double* s_near, double* s_far, int* axis_near,
                  int* axis_far) {
  const double oo[3] = {o.x, o.y, o.z};
  const double dd[3] = {d.x, d.y, d.z};
  const double hh[3] = {h.x, h.y, h.z};
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  int a_lo = 0, a_hi = 0;
  for (int i = 0; i < 3; ++i) {
    if (std::fabs(dd[i]) < 1e-300) {
      if (std::fabs(oo[i]) > hh[i]) return false;
      continue;
    }
    double s1 = (-hh[i] - oo[i]) / dd[i];
    double s2 = (hh[i] - oo[i]) / dd[i];
    if (s1 > s2) std::swap(s1, s2);
    if (s1 > lo) {
      lo = s1;
      a_lo = i;
    }
    if (s2 < hi) {
      hi = s2;
      a_hi = i;
    }
  }
  if (lo > hi) return false;
  *s_near = lo;
  *s_far = hi;
  *axis_near = a_lo;
  *axis_far = a_hi;
  return true;
}

double Component(Vec3 v, int i) { return i == 0 ? v.x : (i == 1 ? v.y : v.z); }

// Texture coordinates on a box face with normal axis `axis`: the other two coordinates,
// offset per face so that faces do not repeat each other.
void FaceUv(Vec3 p, int axis, double sign, double* u, double* v) {
  const double face_offset = 37.0 * axis + (sign > 0 ? 0.0 : 17.0);
  if (axis == 0) {
    *u = p.z + face_offset;
    *v = p.y;
  } else if (axis == 1) {
    *u = p.x + face_offset;
    *v = p.z;
  } else {
    *u = p.x + face_offset;
    *v = p.y;
  }
}

Vec3 AxisVector(int axis, double sign) {
  return {axis == 0 ? sign : 0.0, axis == 1 ? sign : 0.0, axis == 2 ? sign : 0.0};
}

// Intersects one object (ray given in its local frame); updates `best` if nearer.
bool IntersectLocal(const SceneObject& obj, Vec3 o, Vec3 d, double best_depth, Hit* hit) {
  switch (obj.kind) {
    case ShapeKind::kRoom: {
      double s0, s1;
      int a0, a1;
      if (!SlabInterval(o, d, obj.size, &s0, &s1, &a0, &a1) || s1 <= kEps || s1 >= best_depth) {
        return false;
      }
      const Vec3 p = o + s1 * d;
      const double sign = Component(d, a1) > 0 ? 1.0 : -1.0;  // the wall the ray leaves by
      hit->depth = s1;
      hit->local = p;
      hit->local_normal = AxisVector(a1, -sign);  // facing into the room
      FaceUv(p, a1, sign, &hit->u, &hit->v);
      return true;
    }
    case ShapeKind::kBox: {
      double s0, s1;
      int a0, a1;
      if (!SlabInterval(o, d, obj.size, &s0, &s1, &a0, &a1) || s0 <= kEps || s0 >= best_depth) {
        return false;
      }
      const Vec3 p = o + s0 * d;
      const double sign = Component(d, a0) > 0 ? -1.0 : 1.0;  // the face the ray enters by
      hit->depth = s0;
      hit->local = p;
      hit->local_normal = AxisVector(a0, sign);
      FaceUv(p, a0, sign, &hit->u, &hit->v);
      return true;
    }
    case ShapeKind::kSphere: {
      const double r = obj.size.x;
      const double a = Dot(d, d);
      const double b = Dot(o, d);
      const double c = Dot(o, o) - r * r;
      const double disc = b * b - a * c;
      if (disc < 0) return false;
      const double s = (-b - std::sqrt(disc)) / a;
      if (s <= kEps || s >= best_depth) return false;
      const Vec3 p = o + s * d;
      const Vec3 n = (1.0 / r) * p;
      hit->depth = s;
      hit->local = p;
      hit->local_normal = n;
      // Cube map of the direction: the dominant axis picks the face.
      const double ax = std::fabs(n.x), ay = std::fabs(n.y), az = std::fabs(n.z);
      const int axis = (ax >= ay && ax >= az) ? 0 : (ay >= az ? 1 : 2);
      const double major = std::max(ax, std::max(ay, az));
      FaceUv((r / major) * n, axis, Component(n, axis), &hit->u, &hit->v);
      return true;
    }
    case ShapeKind::kCard: {
      if (std::fabs(d.z) < 1e-12) return false;
      const double s = -o.z / d.z;
      if (s <= kEps || s >= best_depth) return false;
      const Vec3 p = o + s * d;
      if (std::fabs(p.x) > obj.size.x || std::fabs(p.y) > obj.size.y) return false;
      hit->depth = s;
      hit->local = {p.x, p.y, 0.0};
      hit->local_normal = {0.0, 0.0, d.z > 0 ? -1.0 : 1.0};
      hit->u = p.x;
      hit->v = p.y;
      return true;
    }
  }
  return false;
}

// Radius of a sphere around the local origin that contains the object.
double BoundingRadius(const SceneObject& obj) {
  switch (obj.kind) {
    case ShapeKind::kSphere:
      return obj.size.x;
    case ShapeKind::kCard:
      return std::sqrt(obj.size.x * obj.size.x + obj.size.y * obj.size.y);
    default:
      return Norm(obj.size);
  }
}

// Camera-space pose at one frame of a body with world pose (orientation q, position t), seen from
// a camera with world pose (orientation qc: camera to world, position c).
Pose CameraSpacePose(Quat qc, Vec3 c, Quat q, Vec3 t) {
  return Pose{ToMatrix(Normalized(Conjugate(qc) * q)), TransposeTimes(ToMatrix(qc), t - c)};
}

// Rotation by a small angle about one axis of the current frame, given s = sin(theta / 2).
Quat AxisRotation(int axis, double s) {
  const double c = std::sqrt(1.0 - s * s);
  return Quat{c, axis == 0 ? s : 0.0, axis == 1 ? s : 0.0, axis == 2 ? s : 0.0};
}

bool InsideBox(Vec3 p, Vec3 centre, Vec3 half) {
  return std::fabs(p.x - centre.x) <= half.x && std::fabs(p.y - centre.y) <= half.y &&
         std::fabs(p.z - centre.z) <= half.z;
}

// The kRobot family (see scene.h). World frame: OpenCV axes at the left camera's start (y down);
// the floor is the plane y = camera height.
// The next texture for `obj`, kept with the scene.
Status AddTexture(Rng& rng, TextureSource& textures, Scene& scene, SceneObject& obj) {
  Result<std::shared_ptr<const Texture>> tex = textures.Next(rng);
  if (!tex.ok()) return tex.status();
  obj.texture = static_cast<int>(scene.textures.size());
  scene.textures.push_back(std::move(tex).value());
  return Status::Ok();
}

// The size of a sphere, box or card (obj.kind) of about `radius`: a box's sides 0.4-0.8 and a
// card's 0.6-1.0 of it, drawn.
void SizeShape(Rng& rng, double radius, SceneObject& obj) {
  if (obj.kind == ShapeKind::kSphere) {
    obj.size = {radius * 0.8, 0, 0};
  } else if (obj.kind == ShapeKind::kBox) {
    obj.size = {radius * rng.Uniform(0.4, 0.8), radius * rng.Uniform(0.4, 0.8),
                radius * rng.Uniform(0.4, 0.8)};
  } else {
    obj.size = {radius * rng.Uniform(0.6, 1.0), radius * rng.Uniform(0.6, 1.0), 0};
  }
}

// The robot scene's room (metres): the rig starts `behind` m from the wall behind it, `ahead` m
// from the one in front, inside the width and at `height` m above the floor.
struct RobotRoom {
  Vec3 half;    // half sizes
  Vec3 centre;  // in the rig's first frame
  double ahead = 0;
};

RobotRoom DrawRobotRoom(Rng& rng) {
  const double height = rng.Uniform(0.3, 1.2);
  const double room_height = rng.Uniform(2.4, 3.4);
  const double room_width = rng.Uniform(3.5, 8.0);
  const double ahead = rng.Uniform(3.0, 7.0);
  const double behind = rng.Uniform(1.0, 3.0);
  RobotRoom room;
  room.half = {room_width / 2, room_height / 2, (ahead + behind) / 2};
  room.centre = {rng.Uniform(-0.5, 0.5) * (room.half.x - 0.8), height - room.half.y,
                 (ahead - behind) / 2};
  room.ahead = ahead;
  return room;
}

// The rig's pose per frame.
struct RigPath {
  std::vector<Quat> q;
  std::vector<Vec3> c;
};

// Ego-motion: constant body-frame velocity and turn rates (a robot driving an arc, slightly
// pitching and rolling); the velocity reverses where the rig would come within 0.6 m of a wall.
RigPath DriveRig(Rng& rng, const SceneOptions& options, const RobotRoom& room, int poses) {
  RigPath path;
  Quat q = Normalized(AxisRotation(1, rng.Uniform(-0.2, 0.2)) *
                      AxisRotation(0, rng.Uniform(-0.05, 0.05)) *
                      AxisRotation(2, rng.Uniform(-0.02, 0.02)));
  const double speed = rng.Uniform() < 0.15
                           ? rng.Uniform(0.0, 0.01)
                           : rng.Uniform(0.01, std::max(0.01, options.max_speed));  // m/frame
  Vec3 v{speed * rng.Uniform(-0.15, 0.15), speed * rng.Uniform(-0.05, 0.05), speed};
  // AxisRotation takes sin(angle / 2); angle / 2 is that within 1e-5 relative here.
  const double pitch = options.max_pitch_rate / 2;
  const Quat turn = Normalized(AxisRotation(1, rng.Uniform(-0.015, 0.015)) *
                               AxisRotation(0, rng.Uniform(-pitch, pitch)) *
                               AxisRotation(2, rng.Uniform(-0.002, 0.002)));
  const Vec3 margin{room.half.x - 0.6, room.half.y - 0.2, room.half.z - 0.6};
  Vec3 c{0, 0, 0};
  for (int t = 0; t < poses; ++t) {
    path.q.push_back(q);
    path.c.push_back(c);
    Vec3 next = c + ToMatrix(q) * v;
    if (!InsideBox(next, room.centre, margin)) {
      v = -1.0 * v;
      next = c + ToMatrix(q) * v;
    }
    c = next;
    q = Normalized(q * turn);
  }
  return path;
}

// A sphere, box or card of 0.12-0.45 m, its shape and gain drawn.
SceneObject DrawRobotShape(Rng& rng) {
  SceneObject obj;
  const int kind = rng.Below(3);
  obj.kind = kind == 0 ? ShapeKind::kSphere : (kind == 1 ? ShapeKind::kBox : ShapeKind::kCard);
  const double radius = rng.Uniform(0.12, 0.45);
  SizeShape(rng, radius, obj);
  obj.gain = rng.Uniform(0.8, 1.2);
  return obj;
}

// Places `obj` in the first view at 0.8-5 m, 35% of them static, the others moving at up to
// 0.08 m per frame (mostly horizontally) and spinning. A place where the object would come
// within 0.3 m of the rig or leave the room is drawn again (up to 20 times): false when none
// fits.
bool PlaceRobotObject(Rng& rng, const Camera& cam, const RobotRoom& room, const RigPath& rig,
                      SceneObject& obj) {
  const double bound = BoundingRadius(obj);
  const Vec3 room_margin{room.half.x - bound, room.half.y - bound, room.half.z - bound};
  const int poses = static_cast<int>(rig.q.size());
  bool placed = false;
  for (int attempt = 0; attempt < 20 && !placed; ++attempt) {
    const double z = rng.Uniform(0.8, std::min(5.0, room.ahead));
    const double col = rng.Uniform(0.05, 0.95) * cam.width;
    const double row = rng.Uniform(0.05, 0.95) * cam.height;
    const Vec3 in_view{(col - cam.cx) * z / cam.focal, (row - cam.cy) * z / cam.focal, z};
    Vec3 t = rig.c[0] + ToMatrix(rig.q[0]) * in_view;
    Quat q = RandomOrientation(rng);
    const bool moving = rng.Uniform() >= 0.35;
    Vec3 v;
    Quat spin;
    if (moving) {
      const Vec3 dir = RandomDirection(rng);
      const double speed = rng.Uniform(0.01, 0.08);
      v = speed * Vec3{dir.x, 0.25 * dir.y, dir.z};
      spin = SmallRotation(rng, rng.Uniform(0.004, 0.03));
    }
    obj.texel_size = rng.Uniform(0.4, 1.2) * z / cam.focal;
    obj.poses.clear();
    placed = InsideBox(t, room.centre, room_margin);
    for (int f = 0; f < poses && placed; ++f) {
      const auto fi = static_cast<size_t>(f);
      if (Norm(t - rig.c[fi]) < bound + 0.3) placed = false;
      obj.poses.push_back(CameraSpacePose(rig.q[fi], rig.c[fi], q, t));
      Vec3 next = t + v;
      if (!InsideBox(next, room.centre, room_margin)) {
        v = -1.0 * v;
        next = t + v;
      }
      t = next;
      q = Normalized(spin * q);
    }
  }
  return placed;
}

Result<Scene> MakeRobotScene(const SceneOptions& options, uint64_t seed, int sequence,
                             TextureSource& textures) {
  const Camera& cam = options.camera;
  Rng rng(MixSeed(seed, static_cast<uint64_t>(sequence), 0x40B07));
  Scene scene;
  scene.camera = cam;
  scene.frames = options.frames;
  const int pose_count = options.frames + 1;
  scene.light = RandomDirection(rng);
  if (scene.light.z > 0) scene.light.z = -scene.light.z;
  scene.ambient = rng.Uniform(0.3, 0.6);
  const RobotRoom room = DrawRobotRoom(rng);
  const RigPath rig = DriveRig(rng, options, room, pose_count);
  SceneObject walls;
  walls.kind = ShapeKind::kRoom;
  walls.size = room.half;
  walls.gain = rng.Uniform(0.8, 1.1);
  walls.texel_size = rng.Uniform(0.5, 1.5) * (0.6 * room.ahead) / cam.focal;
  if (Status s = AddTexture(rng, textures, scene, walls); !s.ok()) return s;
  for (int t = 0; t < pose_count; ++t) {
    const auto ti = static_cast<size_t>(t);
    walls.poses.push_back(CameraSpacePose(rig.q[ti], rig.c[ti], Quat{}, room.centre));
  }
  scene.objects.push_back(std::move(walls));
  for (int i = 0; i < options.objects; ++i) {
    SceneObject obj = DrawRobotShape(rng);
    if (!PlaceRobotObject(rng, cam, room, rig, obj)) continue;  // left out
    if (Status s = AddTexture(rng, textures, scene, obj); !s.ok()) return s;
    scene.objects.push_back(std::move(obj));
  }
  return scene;
}

}  // namespace

bool CastRay(const Scene& scene, int frame, Vec3 origin, Vec3 dir, Hit* hit) {
  *hit = Hit{};
  double best = std::numeric_limits<double>::infinity();
  const double dd = Dot(dir, dir);
  Hit candidate;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& obj = scene.objects[i];
    const Pose& pose = obj.poses[static_cast<size_t>(frame)];
    if (obj.kind != ShapeKind::kRoom) {
      // Quick rejection with the bounding sphere.
      const Vec3 oc = pose.translation - origin;
      const double along = Dot(oc, dir);
      const double r = BoundingRadius(obj);
      if (Dot(oc, oc) - along * along / dd > r * r) continue;
    }
    const Vec3 o = pose.ToLocal(origin);
    const Vec3 d = pose.DirectionToLocal(dir);
    if (IntersectLocal(obj, o, d, best, &candidate)) {
      best = candidate.depth;
      candidate.object = static_cast<int>(i);
      *hit = candidate;
    }
  }
  return hit->object >= 0 && best < std::numeric_limits<double>::infinity();
}

void Shade(const Scene& scene, int frame, const Hit& hit, float bgr[3]) {
  const SceneObject& obj = scene.objects[static_cast<size_t>(hit.object)];
  const Texture& tex = *scene.textures[static_cast<size_t>(obj.texture)];
  tex.Sample(hit.u / obj.texel_size, hit.v / obj.texel_size, bgr);
  const Vec3 n = obj.poses[static_cast<size_t>(frame)].DirectionToCamera(hit.local_normal);
  double lambert = Dot(n, scene.light);
  if (obj.kind == ShapeKind::kCard) lambert = std::fabs(lambert);
  const double shade = (scene.ambient + (1.0 - scene.ambient) * std::max(0.0, lambert)) * obj.gain;
  for (int k = 0; k < 3; ++k) bgr[k] = static_cast<float>(bgr[k] * shade);
}

Result<std::shared_ptr<const Texture>> TextureSource::Next(Rng& rng) {
  if (files_.empty()) return std::make_shared<const Texture>(MakeProceduralTexture(rng));
  const std::string& path = files_[static_cast<size_t>(rng.Below(static_cast<int>(files_.size())))];
  auto it = cache_.find(path);
  if (it != cache_.end()) return it->second;
  Result<Texture> loaded = LoadTextureImage(path);
  if (!loaded.ok()) return loaded.status();
  auto tex = std::make_shared<const Texture>(std::move(loaded).value());
  cache_.emplace(path, tex);
  return std::shared_ptr<const Texture>(tex);
}

namespace {

// What the room scene's draws share: the camera and its half fields of view as slopes (|x| / z
// at the image border).
struct RoomView {
  const Camera& cam;
  double fb = 0;  // focal x baseline
  double x_slope = 0;
  double y_slope = 0;
};

// The room: back wall where the disparity is about 1.2% of the width, side walls seen near the
// image borders. Its motion stands in for the camera's ego-motion.
Status AddRandomRoom(Rng& rng, const RoomView& v, int poses, TextureSource& textures,
                     Scene& scene) {
  const double w = v.cam.width;
  SceneObject room;
  room.kind = ShapeKind::kRoom;
  const double back = v.fb / (0.012 * w) * rng.Uniform(0.8, 1.2);
  room.size = {back * v.x_slope * rng.Uniform(0.6, 1.0), back * v.y_slope * rng.Uniform(0.6, 1.0),
               back};
  room.gain = rng.Uniform(0.8, 1.1);
  room.texel_size = rng.Uniform(0.8, 2.0) * (back * 0.6) / v.cam.focal;
  if (Status s = AddTexture(rng, textures, scene, room); !s.ok()) return s;
  Bounds bounds;
  bounds.x_abs = 0.1 * room.size.x;
  bounds.y_abs = 0.1 * room.size.y;
  bounds.z_max = 0.1 * back;
  const Vec3 t0{rng.Uniform(-0.5, 0.5) * bounds.x_abs, rng.Uniform(-0.5, 0.5) * bounds.y_abs,
                rng.Uniform(-0.5, 0.5) * bounds.z_max};
  const Quat q0 = Normalized(SmallRotation(rng, rng.Uniform(0.0, 0.03)));
  const double speed = back * rng.Uniform(0.002, 0.008);
  const Vec3 velocity = speed * RandomDirection(rng);
  const Quat spin = SmallRotation(rng, rng.Uniform(0.0005, 0.003));
  const double max_half_angle_sin = 0.06;  // net rotation of at most about 7 degrees
  room.poses = MakePoses(t0, q0, velocity, spin, bounds,
                         std::sqrt(1.0 - max_half_angle_sin * max_half_angle_sin), poses);
  scene.objects.push_back(std::move(room));
  return Status::Ok();
}

// An object at a disparity between 2.5% and 15% of the width, its image moving 0.5% to 4% of
// the width per frame and its depth up to 4% per frame.
Status AddRandomObject(Rng& rng, const RoomView& v, int poses, TextureSource& textures,
                       Scene& scene) {
  const Camera& cam = v.cam;
  const double w = cam.width;
  const double h = cam.height;
  const double z_near = v.fb / (0.15 * w);
  const double z_far = v.fb / (0.025 * w);
  SceneObject obj;
  const int kind = rng.Below(3);
  obj.kind = kind == 0 ? ShapeKind::kSphere : (kind == 1 ? ShapeKind::kBox : ShapeKind::kCard);
  const double disparity = rng.Uniform(v.fb / z_far, v.fb / z_near);
  const double z = v.fb / disparity;
  const double radius = rng.Uniform(0.04, 0.15) * w * z / cam.focal;
  SizeShape(rng, radius, obj);
  obj.gain = rng.Uniform(0.8, 1.2);
  obj.texel_size = rng.Uniform(0.7, 2.0) * z / cam.focal;
  if (Status s = AddTexture(rng, textures, scene, obj); !s.ok()) return s;

  const double col = rng.Uniform(0.05, 0.95) * w;
  const double row = rng.Uniform(0.05, 0.95) * h;
  const Vec3 t0{(col - cam.cx) * z / cam.focal, (row - cam.cy) * z / cam.focal, z};
  Bounds bounds;
  bounds.z_min = std::min(z, std::max(v.fb / (0.2 * w), 2.0 * BoundingRadius(obj)));
  bounds.z_max = std::max(z, v.fb / (0.02 * w));
  bounds.x_slope = v.x_slope;
  bounds.y_slope = v.y_slope;
  const Vec3 dir = RandomDirection(rng);
  const double px_speed = rng.Uniform(0.005, 0.04) * w;
  const double planar = std::sqrt(dir.x * dir.x + dir.y * dir.y) + 1e-12;
  const Vec3 velocity{dir.x / planar * px_speed * z / cam.focal,
                      dir.y / planar * px_speed * z / cam.focal, z * rng.Uniform(-0.04, 0.04)};
  const Quat spin = SmallRotation(rng, rng.Uniform(0.004, 0.05));
  obj.poses = MakePoses(t0, RandomOrientation(rng), velocity, spin, bounds, 0.0, poses);
  scene.objects.push_back(std::move(obj));
  return Status::Ok();
}

}  // namespace

Result<Scene> MakeRandomScene(const SceneOptions& options, uint64_t seed, int sequence,
                              TextureSource& textures) {
  if (options.preset == ScenePreset::kRobot) {
    return MakeRobotScene(options, seed, sequence, textures);
  }
  const Camera& cam = options.camera;
  Rng rng(MixSeed(seed, static_cast<uint64_t>(sequence), 0x5CE7E));
  Scene scene;
  scene.camera = cam;
  scene.frames = options.frames;
  const int pose_count = options.frames + 1;
  const double w = cam.width;
  const double h = cam.height;
  const RoomView view{cam, cam.focal * cam.baseline,
                      std::max(cam.cx + 0.5, w - 0.5 - cam.cx) / cam.focal,
                      std::max(cam.cy + 0.5, h - 0.5 - cam.cy) / cam.focal};
  scene.light = RandomDirection(rng);
  if (scene.light.z > 0) scene.light.z = -scene.light.z;  // light from the camera's side
  scene.ambient = rng.Uniform(0.3, 0.6);
  if (Status s = AddRandomRoom(rng, view, pose_count, textures, scene); !s.ok()) return s;
  for (int i = 0; i < options.objects; ++i) {
    if (Status s = AddRandomObject(rng, view, pose_count, textures, scene); !s.ok()) return s;
  }
  return scene;
}

}  // namespace sfrt::synth

// sfrt::camera::Status / Result<T> / ErrorKind: the one error type of camera/v4l2 and
// camera/sources.
#include "sfrt/camera/status.h"

#include <gtest/gtest.h>

#include <cerrno>
#include <iterator>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <utility>

namespace sfrt::camera {
namespace {

TEST(CameraStatus, OkHasKindNoneNoErrnoAndEmptyMessage) {
  for (const Status& s : {Status(), Status::Ok()}) {
    EXPECT_TRUE(s.ok());
    EXPECT_TRUE(static_cast<bool>(s));
    EXPECT_EQ(s.kind(), ErrorKind::kNone);
    EXPECT_EQ(s.sys_errno(), 0);
    EXPECT_EQ(s.message(), "");
  }
}

TEST(CameraStatus, PlainErrorIsGenericWithoutErrno) {
  const Status s = Status::Error("left.yaml: camera_matrix: expected 9 values, got 6");
  EXPECT_FALSE(s.ok());
  EXPECT_FALSE(static_cast<bool>(s));
  EXPECT_EQ(s.kind(), ErrorKind::kGeneric);
  EXPECT_EQ(s.sys_errno(), 0);
  EXPECT_EQ(s.message(), "left.yaml: camera_matrix: expected 9 values, got 6");
}

TEST(CameraStatus, PlainErrorWithEmptyMessageIsStillAnError) {
  const Status s = Status::Error("");
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.kind(), ErrorKind::kGeneric);
}

TEST(CameraStatus, KindedErrorCarriesKindErrnoAndMessage) {
  const Status s =
      Status::Error(ErrorKind::kNoBandwidth, "/dev/video0: VIDIOC_STREAMON: ENOSPC", ENOSPC);
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.kind(), ErrorKind::kNoBandwidth);
  EXPECT_EQ(s.sys_errno(), ENOSPC);
  EXPECT_EQ(s.message(), "/dev/video0: VIDIOC_STREAMON: ENOSPC");

  const Status t = Status::Error(ErrorKind::kTimeout, "/dev/video0: no frame in 1000 ms");
  EXPECT_EQ(t.kind(), ErrorKind::kTimeout);
  EXPECT_EQ(t.sys_errno(), 0);
}

TEST(CameraStatus, CopiesKeepKindErrnoAndMessage) {
  const Status s = Status::Error(ErrorKind::kDisconnected, "/dev/video1: gone", ENODEV);
  Status copy = s;
  EXPECT_EQ(copy.kind(), ErrorKind::kDisconnected);
  EXPECT_EQ(copy.sys_errno(), ENODEV);
  EXPECT_EQ(copy.message(), "/dev/video1: gone");
  copy = Status::Ok();
  EXPECT_TRUE(copy.ok());
  EXPECT_EQ(copy.sys_errno(), 0);
  EXPECT_EQ(copy.message(), "");
}

TEST(CameraStatus, EveryKindHasADistinctName) {
  const ErrorKind kinds[] = {
      ErrorKind::kNone,         ErrorKind::kInvalidArgument,
      ErrorKind::kNotV4l2,      ErrorKind::kUnsupported,
      ErrorKind::kBusy,         ErrorKind::kNoBandwidth,
      ErrorKind::kDisconnected, ErrorKind::kTimeout,
      ErrorKind::kIo,           ErrorKind::kFrameError,
      ErrorKind::kSystem,       ErrorKind::kGeneric,
  };
  std::set<std::string> names;
  for (ErrorKind k : kinds) {
    const std::string name = ErrorKindName(k);
    EXPECT_NE(name, "unknown") << static_cast<int>(k);
    names.insert(name);
  }
  EXPECT_EQ(names.size(), std::size(kinds));
  static_assert(ErrorKindName(ErrorKind::kNone) == std::string_view("ok"));
  EXPECT_STREQ(ErrorKindName(ErrorKind::kBusy), "busy");
}

TEST(CameraResult, ValueIsReachableEveryWay) {
  Result<std::string> r(std::string("abc"));
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r.status().ok());
  EXPECT_EQ(r.message(), "");
  EXPECT_EQ(r.value(), "abc");
  EXPECT_EQ(*r, "abc");
  EXPECT_EQ(r->size(), 3u);
  const Result<std::string>& cr = r;
  EXPECT_EQ(*cr, "abc");
  EXPECT_EQ(cr->size(), 3u);
  std::string moved = std::move(r).value();
  EXPECT_EQ(moved, "abc");
}

TEST(CameraResult, ErrorKeepsTheWholeStatus) {
  Result<std::unique_ptr<int>> r = Status::Error(ErrorKind::kBusy, "/dev/video0: EBUSY", EBUSY);
  EXPECT_FALSE(r.ok());
  EXPECT_FALSE(static_cast<bool>(r));
  EXPECT_EQ(r.status().kind(), ErrorKind::kBusy);
  EXPECT_EQ(r.status().sys_errno(), EBUSY);
  EXPECT_EQ(r.message(), "/dev/video0: EBUSY");

  Result<int> plain = Status::Error("frames/0001.png: cannot decode");
  EXPECT_EQ(plain.status().kind(), ErrorKind::kGeneric);
  EXPECT_EQ(plain.message(), "frames/0001.png: cannot decode");
}

}  // namespace
}  // namespace sfrt::camera

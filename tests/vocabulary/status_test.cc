// One Status for every module (sfrt/vocabulary/status.h): the runtime's sfrt/status.h and
// camera's sfrt/camera/status.h name the same type, so a camera error reaches the pipeline, the
// tools and the runtime's callers with its kind and errno, and an ok Status holds no memory.
#include "sfrt/vocabulary/status.h"

#include <gtest/gtest.h>

#include <cerrno>
#include <string>
#include <type_traits>

#include "sfrt/status.h"
#ifdef SFRT_TEST_CAMERA_STATUS
#include "sfrt/camera/status.h"
static_assert(std::is_same_v<sfrt::camera::Status, sfrt::Status>);
static_assert(std::is_same_v<sfrt::camera::Result<int>, sfrt::Result<int>>);
static_assert(std::is_same_v<sfrt::camera::ErrorKind, sfrt::ErrorKind>);
#endif

namespace sfrt {
namespace {

Result<int> Busy() {
  return Status::Error(ErrorKind::kBusy, "/dev/video0: VIDIOC_STREAMON: EBUSY", EBUSY);
}

TEST(OneStatus, AnErrorKeepsItsKindAndErrnoThroughAResult) {
  const Result<int> r = Busy();
  ASSERT_FALSE(r.ok());
  const Status passed_on = r.status();  // what a pipeline function returns for it
  EXPECT_EQ(passed_on.kind(), ErrorKind::kBusy);
  EXPECT_EQ(passed_on.sys_errno(), EBUSY);
  EXPECT_EQ(passed_on.message(), "/dev/video0: VIDIOC_STREAMON: EBUSY");
  EXPECT_STREQ(ErrorKindName(passed_on.kind()), "busy");
}

TEST(OneStatus, AMessageOnlyErrorIsGenericAndOkIsEmpty) {
  const Status generic = Status::Error("model.sfrt: layer 'conv0': bad stride");
  EXPECT_FALSE(generic.ok());
  EXPECT_EQ(generic.kind(), ErrorKind::kGeneric);
  EXPECT_EQ(generic.sys_errno(), 0);
  const Status ok = Status::Ok();
  EXPECT_TRUE(ok.ok());
  EXPECT_EQ(ok.kind(), ErrorKind::kNone);
  EXPECT_TRUE(ok.message().empty());
  EXPECT_EQ(ok.message().capacity(), std::string().capacity()) << "an ok Status holds no heap";
}

}  // namespace
}  // namespace sfrt

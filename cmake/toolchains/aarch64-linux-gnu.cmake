# Cross build for 64-bit ARM Linux with Debian's cross toolchain (crossbuild-essential-arm64 /
# g++-aarch64-linux-gnu); tests run under qemu-user (qemu-aarch64) with the target's libraries.
#   cmake --preset aarch64 && cmake --build --preset aarch64 && ctest --preset aarch64
# Only the runtime and the tests that need nothing else build this way (SFRT_BUILD_EXPORTER and
# SFRT_BUILD_TOOLS off): FlatBuffers is used header-only and flatc runs on the build machine;
# GoogleTest is compiled from Debian's sources (/usr/src/googletest, libgtest-dev).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_FIND_ROOT_PATH /usr/aarch64-linux-gnu)
# Programs (flatc) and CMake package files (FlatBuffers' flatc target) come from the build
# machine; libraries and headers only from the target root.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_CROSSCOMPILING_EMULATOR "qemu-aarch64;-L;/usr/aarch64-linux-gnu" CACHE STRING
    "Runs target programs (tests) on the build machine")
# FlatBuffers' package (for the flatc target; its headers are used header-only) is the build
# machine's.
set(FlatBuffers_DIR /usr/lib/${CMAKE_HOST_SYSTEM_PROCESSOR}-linux-gnu/cmake/flatbuffers
    CACHE PATH "FlatBuffers CMake package of the build machine")

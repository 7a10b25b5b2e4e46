# GoogleTest for the test suite: the installed package natively; when cross-compiling, built
# from Debian's sources (libgtest-dev ships them in /usr/src/googletest) for the target.
# Provides GTest::gtest and GTest::gtest_main either way.
if(CMAKE_CROSSCOMPILING)
  set(SFRT_GTEST_SOURCE_DIR /usr/src/googletest CACHE PATH "GoogleTest sources for cross builds")
  if(NOT EXISTS ${SFRT_GTEST_SOURCE_DIR}/CMakeLists.txt)
    message(FATAL_ERROR "cross build: no GoogleTest sources at SFRT_GTEST_SOURCE_DIR="
                        "${SFRT_GTEST_SOURCE_DIR} (install libgtest-dev)")
  endif()
  set(BUILD_GMOCK OFF CACHE BOOL "" FORCE)
  set(INSTALL_GTEST OFF CACHE BOOL "" FORCE)
  add_subdirectory(${SFRT_GTEST_SOURCE_DIR} ${CMAKE_BINARY_DIR}/googletest EXCLUDE_FROM_ALL)
  if(NOT TARGET GTest::gtest)
    add_library(GTest::gtest ALIAS gtest)
    add_library(GTest::gtest_main ALIAS gtest_main)
  endif()
else()
  find_package(GTest REQUIRED)
endif()

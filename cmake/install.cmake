# The installed package: `cmake --install <build> --prefix <p>` puts the headers, the static
# libraries (and the runtime's shared one) and sfrtConfig.cmake/sfrtConfigVersion.cmake under <p>;
# a program outside the tree then uses
#   find_package(sfrt 0.2 REQUIRED)
#   target_link_libraries(robot PRIVATE sfrt::runtime)          # static
#   target_link_libraries(robot PRIVATE sfrt::runtime_shared)   # or the shared library
#   target_link_libraries(robot PRIVATE sfrt::pipeline)         # cameras -> flow, sinks
# sfrt::runtime needs the C++ standard library and threads only (FlatBuffers is compiled in).
# With SFRT_BUILD_PIPELINE (the default) the package also has sfrt::camera (and its parts
# sfrt::camera_common, _yuv, _v4l2, _sources), sfrt::config (deployment profiles), sfrt::pipeline_io
# and sfrt::pipeline; those find OpenCV, yaml-cpp, nlohmann-json and libturbojpeg on the
# consumer's machine (sfrt_HAS_PIPELINE says so in sfrtConfig.cmake).
# tests/install/ builds such programs against a fresh install in the test suite.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(SFRT_CMAKE_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/sfrt)

set(SFRT_INSTALLED_TARGETS sfrt_vocabulary sfrt_runtime sfrt_runtime_shared)
set(SFRT_INSTALLED_HEADER_DIRS ${PROJECT_SOURCE_DIR}/vocabulary/include/sfrt
  ${PROJECT_SOURCE_DIR}/runtime/include/sfrt)
set(SFRT_PACKAGE_HAS_PIPELINE OFF)
if(TARGET sfrt_pipeline)
  set(SFRT_PACKAGE_HAS_PIPELINE ON)
  list(APPEND SFRT_INSTALLED_TARGETS sfrt_camera sfrt_camera_common sfrt_camera_yuv sfrt_camera_v4l2
       sfrt_camera_sources sfrt_config_vocabulary sfrt_config sfrt_pipeline_io sfrt_pipeline)
  list(APPEND SFRT_INSTALLED_HEADER_DIRS ${PROJECT_SOURCE_DIR}/camera/common/include/sfrt
       ${PROJECT_SOURCE_DIR}/camera/v4l2/include/sfrt
       ${PROJECT_SOURCE_DIR}/camera/sources/include/sfrt
       ${PROJECT_SOURCE_DIR}/firmware-cfg/include/sfrt ${PROJECT_SOURCE_DIR}/pipeline/include/sfrt)
endif()
install(TARGETS ${SFRT_INSTALLED_TARGETS} EXPORT sfrtTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${SFRT_INSTALLED_HEADER_DIRS}
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} FILES_MATCHING PATTERN "*.h")
install(EXPORT sfrtTargets NAMESPACE sfrt:: DESTINATION ${SFRT_CMAKE_INSTALL_DIR})

configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/sfrtConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/sfrtConfig.cmake INSTALL_DESTINATION ${SFRT_CMAKE_INSTALL_DIR})
# 0.x: a new minor version may change the API, so only the same minor version is compatible.
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/sfrtConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/sfrtConfig.cmake
  ${CMAKE_CURRENT_BINARY_DIR}/sfrtConfigVersion.cmake DESTINATION ${SFRT_CMAKE_INSTALL_DIR})

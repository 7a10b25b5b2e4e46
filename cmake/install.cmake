# The installed package: `cmake --install <build> --prefix <p>` puts the runtime's headers, its
# static and shared libraries and sfrtConfig.cmake/sfrtConfigVersion.cmake under <p>; a program
# outside the tree then uses
#   find_package(sfrt 0.2 REQUIRED)
#   target_link_libraries(robot PRIVATE sfrt::runtime)          # static
#   target_link_libraries(robot PRIVATE sfrt::runtime_shared)   # or the shared library
# sfrt::runtime needs the C++ standard library and threads only (FlatBuffers is compiled in).
# tests/install/ builds such a program against a fresh install in the test suite.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(SFRT_CMAKE_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/sfrt)

install(TARGETS sfrt_runtime sfrt_runtime_shared EXPORT sfrtTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/runtime/include/sfrt
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} FILES_MATCHING PATTERN "*.h")
install(EXPORT sfrtTargets NAMESPACE sfrt:: DESTINATION ${SFRT_CMAKE_INSTALL_DIR})

configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/sfrtConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/sfrtConfig.cmake INSTALL_DESTINATION ${SFRT_CMAKE_INSTALL_DIR})
# 0.x: a new minor version may change the API, so only the same minor version is compatible.
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/sfrtConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/sfrtConfig.cmake
  ${CMAKE_CURRENT_BINARY_DIR}/sfrtConfigVersion.cmake DESTINATION ${SFRT_CMAKE_INSTALL_DIR})

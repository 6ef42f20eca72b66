# Install rules and the CMake package config, so that a consumer can write
#   find_package(opl REQUIRED)
#   target_link_libraries(app PRIVATE opl::opl)
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

install(TARGETS opl EXPORT oplTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY include/opl DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT oplTargets NAMESPACE opl:: FILE oplTargets.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/opl)
configure_package_config_file(cmake/oplConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/oplConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/opl)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/oplConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/oplConfig.cmake
  ${CMAKE_CURRENT_BINARY_DIR}/oplConfigVersion.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/opl)

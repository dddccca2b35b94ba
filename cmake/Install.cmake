# Install rules and the CMake package: `cmake --install build --prefix P` puts the CPU libraries
# (splatwarp_core, splatwarp_vdb, splatwarp_job; static), their headers, the CLI, a config
# package (find_package(splatwarp CONFIG) -> splatwarp::core, splatwarp::vdb, splatwarp::job,
# splatwarp::cli) and a pkg-config file under P. tests/package/ builds a consumer against it.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(SPLATWARP_INSTALL_INCLUDE ${CMAKE_INSTALL_INCLUDEDIR}/splatwarp)
set(SPLATWARP_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/splatwarp)

# The libraries name their source folders as include paths; installed, the headers keep the same
# relative layout: include/splatwarp/{core,io,...}, include/splatwarp/vdb, include/splatwarp/job.
function(splatwarp_installed_includes target)
  get_target_property(dirs ${target} INTERFACE_INCLUDE_DIRECTORIES)
  set(wrapped)
  foreach(dir ${dirs})
    list(APPEND wrapped "$<BUILD_INTERFACE:${dir}>")
  endforeach()
  list(APPEND wrapped ${ARGN})
  set_target_properties(${target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${wrapped}")
endfunction()
splatwarp_installed_includes(splatwarp_core "$<INSTALL_INTERFACE:${SPLATWARP_INSTALL_INCLUDE}>"
                             "$<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>")
splatwarp_installed_includes(splatwarp_vdb "$<INSTALL_INTERFACE:${SPLATWARP_INSTALL_INCLUDE}/vdb>")
splatwarp_installed_includes(splatwarp_job "$<INSTALL_INTERFACE:${SPLATWARP_INSTALL_INCLUDE}/job>")

set_target_properties(splatwarp_core PROPERTIES EXPORT_NAME core)
set_target_properties(splatwarp_vdb PROPERTIES EXPORT_NAME vdb)
set_target_properties(splatwarp_job PROPERTIES EXPORT_NAME job)
set_target_properties(splatwarp PROPERTIES EXPORT_NAME cli)
install(TARGETS splatwarp_core splatwarp_vdb splatwarp_job EXPORT splatwarpTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS splatwarp EXPORT splatwarpTargets RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

install(DIRECTORY ${CMAKE_SOURCE_DIR}/src/ DESTINATION ${SPLATWARP_INSTALL_INCLUDE} FILES_MATCHING PATTERN "*.h")
install(DIRECTORY ${CMAKE_SOURCE_DIR}/vdb/ DESTINATION ${SPLATWARP_INSTALL_INCLUDE}/vdb FILES_MATCHING PATTERN "*.h")
install(DIRECTORY ${CMAKE_SOURCE_DIR}/job/ DESTINATION ${SPLATWARP_INSTALL_INCLUDE}/job FILES_MATCHING PATTERN "*.h")
install(FILES ${CMAKE_BINARY_DIR}/generated/splatwarp/Version.h DESTINATION ${SPLATWARP_INSTALL_INCLUDE})

install(EXPORT splatwarpTargets NAMESPACE splatwarp:: DESTINATION ${SPLATWARP_CMAKE_DIR})
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/splatwarpConfig.cmake.in
                              ${CMAKE_BINARY_DIR}/splatwarpConfig.cmake INSTALL_DESTINATION ${SPLATWARP_CMAKE_DIR})
write_basic_package_version_file(${CMAKE_BINARY_DIR}/splatwarpConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/splatwarpConfig.cmake ${CMAKE_BINARY_DIR}/splatwarpConfigVersion.cmake
        DESTINATION ${SPLATWARP_CMAKE_DIR})

file(RELATIVE_PATH SPLATWARP_PC_TO_PREFIX "/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/")
configure_file(${CMAKE_SOURCE_DIR}/cmake/splatwarp.pc.in ${CMAKE_BINARY_DIR}/splatwarp.pc @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/splatwarp.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

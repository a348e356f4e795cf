# The installed tree: the libraries and headers as a CMake package (find_package(stampede) gives
# stampede::app, stampede::io, stampede::engine, stampede::kernels) and a pkg-config file
# (stampede.pc), the `stampede` command, and (python/CMakeLists.txt) the Python package.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(STAMPEDE_LIBRARIES stampede_kernels stampede_engine stampede_io stampede_app)
foreach(lib IN LISTS STAMPEDE_LIBRARIES)
  string(REPLACE "stampede_" "" short "${lib}")
  set_target_properties(${lib} PROPERTIES EXPORT_NAME ${short})
  add_library(stampede::${short} ALIAS ${lib})
endforeach()
install(TARGETS ${STAMPEDE_LIBRARIES} EXPORT stampedeTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS stampede RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# Headers keep the tree's layout under include/stampede/, so "engine/fit/fitter.hpp" resolves as in
# the build.
foreach(dir kernels engine io app)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/stampede
          FILES_MATCHING PATTERN "*.hpp")
endforeach()

set(STAMPEDE_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/stampede)
install(EXPORT stampedeTargets NAMESPACE stampede:: DESTINATION ${STAMPEDE_CMAKE_DIR})
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/stampedeConfig.cmake.in
                              ${CMAKE_CURRENT_BINARY_DIR}/stampedeConfig.cmake INSTALL_DESTINATION ${STAMPEDE_CMAKE_DIR})
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/stampedeConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/stampedeConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/stampedeConfigVersion.cmake
        DESTINATION ${STAMPEDE_CMAKE_DIR})

file(RELATIVE_PATH STAMPEDE_PC_TO_PREFIX "/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/")
string(REGEX REPLACE "/$" "" STAMPEDE_PC_TO_PREFIX "${STAMPEDE_PC_TO_PREFIX}")
configure_file(${CMAKE_CURRENT_LIST_DIR}/stampede.pc.in ${CMAKE_CURRENT_BINARY_DIR}/stampede.pc @ONLY)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/stampede.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

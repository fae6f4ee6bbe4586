# libstipple as one static and one shared library made of every library module's objects, and
# its installed CMake package: find_package(stipple) gives stipple::stipple (shared) and
# stipple::static.
set(objects)
set(build_includes)
foreach(m ${STIPPLE_LIBRARY_MODULES})
  list(APPEND objects $<TARGET_OBJECTS:stipple_${m}>)
  list(APPEND build_includes $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/${m}/include>)
endforeach()
get_property(public_libs GLOBAL PROPERTY STIPPLE_PUBLIC_LIBS)
get_property(private_libs GLOBAL PROPERTY STIPPLE_PRIVATE_LIBS)
list(REMOVE_DUPLICATES public_libs)
list(REMOVE_DUPLICATES private_libs)

# The shared library exports the WebGPU forwarders (see src/renderer/CMakeLists.txt).
set(static_objects ${objects})
set(shared_objects $<FILTER:${objects},EXCLUDE,webgpu_loader_gen> $<TARGET_OBJECTS:stipple_webgpu_exports>)
foreach(kind static shared)
  string(TOUPPER ${kind} KIND)
  add_library(stipple_${kind} ${KIND} ${${kind}_objects})
  target_include_directories(stipple_${kind} PUBLIC ${build_includes}
    $<BUILD_INTERFACE:${STIPPLE_WEBGPU_INCLUDE}> $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_compile_features(stipple_${kind} PUBLIC cxx_std_20)
  set_target_properties(stipple_${kind} PROPERTIES OUTPUT_NAME stipple
    ARCHIVE_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR} LIBRARY_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR})
endforeach()
# A static archive needs everything its objects use at the final link; the shared library
# resolves its own dependencies and exposes only what its headers include.
target_link_libraries(stipple_static PUBLIC ${public_libs} ${private_libs})
target_link_libraries(stipple_shared PUBLIC ${public_libs} PRIVATE ${private_libs})
set_target_properties(stipple_static PROPERTIES EXPORT_NAME static)
set_target_properties(stipple_shared PROPERTIES EXPORT_NAME stipple VERSION ${PROJECT_VERSION}
  SOVERSION ${PROJECT_VERSION_MAJOR})

install(TARGETS stipple_static stipple_shared EXPORT stippleTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(FILES ${STIPPLE_WEBGPU_INCLUDE}/webgpu/webgpu.h ${STIPPLE_WEBGPU_INCLUDE}/webgpu/wgpu.h
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/webgpu)
include(CMakePackageConfigHelpers)
set(config_dir ${CMAKE_INSTALL_LIBDIR}/cmake/stipple)
install(EXPORT stippleTargets NAMESPACE stipple:: DESTINATION ${config_dir})
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/stippleConfig.cmake.in
  ${CMAKE_BINARY_DIR}/stippleConfig.cmake INSTALL_DESTINATION ${config_dir})
write_basic_package_version_file(${CMAKE_BINARY_DIR}/stippleConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/stippleConfig.cmake ${CMAKE_BINARY_DIR}/stippleConfigVersion.cmake
  DESTINATION ${config_dir})

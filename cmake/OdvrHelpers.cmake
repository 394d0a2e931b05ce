# Warnings for our own targets only; -Werror is switched on by CI (ODVR_WERROR).
function(odvr_target_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wshadow -Wnon-virtual-dtor -Wno-missing-field-initializers)
  if(ODVR_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# Embeds every shaders/*.glsl, *.comp, *.vert, *.frag into a generated .cpp at build time,
# so the program runs from any directory. glslangValidator (if installed) checks each file first,
# so a syntax error is a build error with file and line.
function(odvr_embed_shaders target shader_dir)
  file(GLOB shader_files CONFIGURE_DEPENDS
       "${shader_dir}/*.glsl" "${shader_dir}/*.comp" "${shader_dir}/*.vert" "${shader_dir}/*.frag")
  list(SORT shader_files)
  set(generated "${CMAKE_CURRENT_BINARY_DIR}/generated/embedded_shaders.cpp")
  find_program(GLSLANG_VALIDATOR glslangValidator)
  set(check_stamps)
  if(GLSLANG_VALIDATOR)
    # Ninja makes an output's folder itself; other generators do not.
    file(MAKE_DIRECTORY "${CMAKE_CURRENT_BINARY_DIR}/generated/checked")
    foreach(file IN LISTS shader_files)
      get_filename_component(fname "${file}" NAME)
      get_filename_component(ext "${file}" EXT)
      if(NOT ext STREQUAL ".glsl")  # included snippets are checked through their users
        set(stamp "${CMAKE_CURRENT_BINARY_DIR}/generated/checked/${fname}.ok")
        add_custom_command(OUTPUT "${stamp}"
          COMMAND "${GLSLANG_VALIDATOR}" -l "-I${shader_dir}" "${file}" > /dev/null
          COMMAND ${CMAKE_COMMAND} -E touch "${stamp}"
          DEPENDS "${file}" ${shader_files}
          COMMENT "Checking GLSL ${fname}" VERBATIM)
        list(APPEND check_stamps "${stamp}")
      endif()
    endforeach()
  endif()
  add_custom_command(OUTPUT "${generated}"
    COMMAND ${CMAKE_COMMAND} -DOUTPUT=${generated} -DSHADER_DIR=${shader_dir}
            -P "${PROJECT_SOURCE_DIR}/cmake/EmbedShaders.cmake"
    DEPENDS ${shader_files} ${check_stamps} "${PROJECT_SOURCE_DIR}/cmake/EmbedShaders.cmake"
    COMMENT "Embedding GLSL shaders" VERBATIM)
  add_library(${target} STATIC "${generated}")
  set_target_properties(${target} PROPERTIES POSITION_INDEPENDENT_CODE ON)
endfunction()

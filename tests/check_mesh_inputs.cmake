# Gives a program a mesh path it cannot read and checks that it fails with a one-line message
# saying why, without waiting: ctest's TIMEOUT fails a program that blocks on the FIFO.
#   cmake -DTOOL=<tool> -DEXE=<program> -DKIND=<kind> -DDIR=<folder> -P check_mesh_inputs.cmake
# TOOL: inspect, bench, render_scene, render_set, render_mesh, ray_costs or construction (whose
# input is a triangle file). KIND: fifo, device (/dev/zero), directory, missing, or claims (an
# OFF file of 34 bytes whose header claims a billion vertices and faces). render_scene names the
# mesh in a scene file, render_set with --set MESH=. kdrt-inspect, kdrt-render-mesh,
# kdrt-ray-costs and kdrt-construction must fail with status 1 and the one line
# "PROGRAM: cannot read 'PATH': REASON".
file(MAKE_DIRECTORY ${DIR})
set(mesh ${DIR}/${KIND}.off)
file(REMOVE_RECURSE ${mesh})
if(KIND STREQUAL "fifo")
  execute_process(COMMAND mkfifo ${mesh} RESULT_VARIABLE failed)
  if(failed)
    message(FATAL_ERROR "mkfifo ${mesh} failed")
  endif()
  set(expect "it is not a regular file \\(a FIFO\\)")
elseif(KIND STREQUAL "device")
  set(mesh /dev/zero)
  set(expect "it is not a regular file \\(a character device\\)")
elseif(KIND STREQUAL "directory")
  file(MAKE_DIRECTORY ${mesh})
  set(expect "it is a directory")
  if(TOOL STREQUAL "render_scene")
    set(expect "is a folder, not a file")
  elseif(TOOL STREQUAL "bench")  # kdrt-bench reads the meshes in a folder
    set(expect "skipping ${mesh}: a folder with no mesh files")
  endif()
elseif(KIND STREQUAL "missing")
  set(expect "no such file")
  if(TOOL STREQUAL "render_scene")
    set(expect "cannot be read: No such file or directory")
  elseif(TOOL STREQUAL "construction")
    set(expect "No such file or directory")
  endif()
elseif(KIND STREQUAL "claims")
  file(WRITE ${mesh} "OFF\n1000000000 1000000000 0\n0 0 0\n")
  set(expect "refused: reading it asked for [0-9,]+ bytes of memory at once, more than the [0-9,]+ that 34 bytes of mesh file may take")
else()
  message(FATAL_ERROR "unknown KIND '${KIND}'")
endif()

set(program "")  # the tools held to "PROGRAM: cannot read 'PATH': REASON"
if(TOOL STREQUAL "inspect")
  set(command ${EXE} ${mesh})
  set(program kdrt-inspect)
elseif(TOOL STREQUAL "render_mesh")
  set(command ${EXE} ${mesh} --size 8x6 -o ${DIR}/${KIND}.png)
  set(program kdrt-render-mesh)
elseif(TOOL STREQUAL "ray_costs")
  set(command ${EXE} --size 8x8 --repeat 1 ${mesh})
  set(program kdrt-ray-costs)
elseif(TOOL STREQUAL "construction")
  set(command ${EXE} ${mesh} -o ${DIR}/${KIND}.json)
  set(program kdrt-construction)
elseif(TOOL STREQUAL "bench")
  set(command ${EXE} --size 8x8 --leaf-sizes 1 ${mesh} -o ${DIR}/${KIND}.csv)
elseif(TOOL STREQUAL "render_scene")
  file(WRITE ${DIR}/${KIND}.yaml "camera: {position: [0, 1, 4], target: [0, 0.5, 0]}\n"
    "materials: [{name: white}]\nmeshes: [{file: ${mesh}, material: white}]\n"
    "lights: [{type: sphere, center: [1, 3, 2], radius: 0.2}]\n")
  set(command ${EXE} --scene ${DIR}/${KIND}.yaml --size 8x6 -o ${DIR}/${KIND}.png)
elseif(TOOL STREQUAL "render_set")
  set(command ${EXE} --preset PICTURE --set MESH=${mesh} --size 8x6 -o ${DIR}/${KIND}.png)
else()
  message(FATAL_ERROR "unknown TOOL '${TOOL}'")
endif()

execute_process(COMMAND ${command} OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE status)
if(status EQUAL 0)
  message(FATAL_ERROR "${TOOL} succeeded on ${mesh} (${KIND}):\n${out}${err}")
endif()
if(NOT "${out}${err}" MATCHES "${expect}")
  message(FATAL_ERROR "${TOOL} on ${mesh} (${KIND}) did not say '${expect}' (exit ${status}):\n${out}${err}")
endif()
if(program)
  string(REGEX REPLACE "([][+.*()^$?|\\\\])" "\\\\\\1" quoted "${mesh}")
  if(NOT status EQUAL 1 OR NOT "${err}" MATCHES "^${program}: cannot read '${quoted}': ${expect}[^\n]*\n$")
    message(FATAL_ERROR "${TOOL} on ${mesh} (${KIND}): not exit 1 and the one line "
                        "\"${program}: cannot read '${mesh}': ...\" (exit ${status}):\n${err}")
  endif()
endif()
message(STATUS "${TOOL} on ${KIND}: ${err}")

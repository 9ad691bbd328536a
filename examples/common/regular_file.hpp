// Input files opened only when they are regular files: a FIFO blocks open() until a writer comes,
// and a device such as /dev/zero never ends. For the meshes Assimp reads and the files a scene
// names.
#pragma once

#include <sys/stat.h>

#include <cstdio>
#include <string>

namespace common {

// Opens `path` for reading ("rb") if it is a regular file, without ever blocking: the type is
// checked on the file opened. Otherwise nullptr, and `why` says why: "it is a directory", "it is
// not a regular file (a FIFO)" (or a character device, ...), or the system's message. `st` gets
// the file's status.
std::FILE *open_regular_file(const char *path, struct stat &st, std::string &why);

// Why a file of this type is not a regular file, as above; "" for a regular file.
std::string not_regular(const struct stat &st);

}  // namespace common

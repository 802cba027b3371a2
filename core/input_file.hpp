// Reading an input file (a scene, a nodal CSV file) without ever blocking on a special file.
//
// The file is opened with O_NONBLOCK and the descriptor is fstat'ed (no check-then-open race):
// a directory, a socket, a character device (/dev/zero, /dev/tty), a block device and, unless
// pipes are allowed, a FIFO are refused with the reason; a regular file is read up to a bound, so
// neither an endless file nor a huge one exhausts memory. Allowed pipes (`crossdyn run <(...)`,
// /dev/stdin) are read in blocking mode after the open: a FIFO nobody writes to reads as empty at
// once instead of waiting in open() for a writer.
#pragma once

#include <cstddef>
#include <string>

namespace crossdyn {

struct InputFile {
  std::string text;     // at most max_bytes + 1 bytes: more than max_bytes means "too large"
  std::string problem;  // why it cannot be read ("" when it was read), e.g. "it is a directory"
  bool pipe = false;    // it was a pipe or FIFO
};

enum class Pipes { Refuse, Allow };

// Reads `path` as described above. Never throws for the file's sake (only std::bad_alloc).
// `noun` ends the directory message: "it is a directory, not a scene file".
InputFile read_input_file(const std::string& path, std::size_t max_bytes, Pipes pipes,
                          const char* noun = "file");

// Why `path` cannot be read as an input file ("" when it can): the open and fstat of
// read_input_file without the read (the report script, which python reads).
std::string input_file_problem(const std::string& path, Pipes pipes, const char* noun = "file");

}  // namespace crossdyn

// SHA-256 (FIPS 180-4) of a byte string, as 64 lowercase hex digits: the scene hashes of sharded
// verify's part files (harness/shard.hpp). Small and dependency-free; not for secrets.
#pragma once

#include <string>
#include <string_view>

namespace crossdyn::harness {

std::string sha256_hex(std::string_view bytes);

}  // namespace crossdyn::harness

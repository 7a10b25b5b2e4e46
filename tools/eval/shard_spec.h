// The vocabulary of a job split over N machines (sfrt eval --shard, sfrt run --shard): shard
// `index` of `count`. The work list and the merge are eval/shards.h's; the flag is
// sfrt/shard_args.h's.
#pragma once

namespace sfrt::eval {

struct ShardSpec {
  int index = 0;
  int count = 1;
};

}  // namespace sfrt::eval

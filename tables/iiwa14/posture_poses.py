#!/usr/bin/env python3
"""Joint vectors for `tablec simulate --poses`: the 7-axis arm in many postures per region.

Usage: posture_poses.py SEED COUNT > poses.csv
"""
import random, sys
# Joint vectors of a 7-axis arm drawn uniformly in ranges that keep the flange in front of
# the robot, every posture of the elbow (j3) equally likely: j1..j7, degrees.
seed, count = int(sys.argv[1]), int(sys.argv[2])
rng = random.Random(seed)
ranges = [(-40, 40), (15, 65), (-60, 60), (-105, -55), (-45, 45), (-60, 60), (-90, 90)]
# x,y,z: columns the poses reader requires; `tablec simulate --poses` measures the joints.
print("x,y,z,j1,j2,j3,j4,j5,j6,j7")
for _ in range(count):
    print("0,0,0," + ",".join(f"{rng.uniform(lo, hi):.4f}" for lo, hi in ranges))

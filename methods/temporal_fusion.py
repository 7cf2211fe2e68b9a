"""`temporal-fusion`: fill each hole from every frame that saw the missing surface, motion-compensated,
fused, projected onto the surface and kept steady over time; a spatial fill only where no frame saw it.

Not a method from the paper. It starts from what our measurements (methods/NOTES.md) showed: where a
neighbouring frame holds the missing patch, a rigidly aligned copy of it (`temporal-copy`) beats any
graph fill by 10 dB; where no frame holds it (coherent holes, occlusions), a spatial fill is needed,
and it must sit on the surface and stay put from frame to frame.

Units. Lengths are in point spacings ``s`` (`holes.geometry.point_spacing` of the largest frame:
median 8th-NN distance / sqrt(2); exactly 1 voxel on voxelized data) or in hole sizes (the region's
bounding radius ``r``); time is in frames.

Pipeline. Frames are processed in order (step 5 reuses frame f-1's result), then once more from the last
to the first for the holes left open (step 9 takes frame f+1's). For frame f and each of
its hole regions R (given, or found by `holes.detection.detect_holes` per frame when regions=None):
(code: steps 1-5, 7, 7b, 8 and 9 here; the spatial fills of steps 6, 6c-6f and step 4's agreement rule in
`methods._spatial_fill`; step 6b in `methods._front_fill`)

1. Rim shell: the points of frame f within ``shell = max(shell_factor * r, shell_spacings * s)``
   of R (points inside R, where an oriented occlusion box keeps some, count too: they are data).
1b. Thin gaps on voxelized data (``rim_fill``): the gap is first grown from frame f's own rim by the
   voxelization rule (`crossed_voxels`): each round judges the free voxels of R within sqrt 3 (the
   26-neighbourhood) of the rim and of the voxels accepted so far, and accepts a voxel when the MLS
   quadric of its ``mls_neighbours`` nearest support points crosses its unit cube,
   |(c - p) . n| <= (|n_x| + |n_y| + |n_z|) / 2 (p the foot point, n the unit normal: the exact
   plane-cube test, the rule voxelized captures and our stand-ins are made by). When the growth
   closes (a round accepts nothing, or nothing is left to judge) within ceil(sqrt(k / pi)) rounds
   (k = ``mls_neighbours``: the radius, in spacings, of the disc the fit's k points cover; 3 for
   k = 20 and 28), the gap is thin, every new voxel lies within one fit radius of captured points, and the
   result is R's fill: steps 2-8 are skipped for R. Otherwise the growth is discarded and R is filled
   by steps 2-8. Why: occlusion holes (armpits, crotch, crown, soles) are thin gaps between captured
   points in places no camera saw in any frame; there a motion-compensated copy of a neighbour sits
   up to a voxel off (those places fold and slide), and the spline of step 6 failed its tests or
   sat off the surface, while the frame's own rim, a voxel or two away, fixes the surface. Measured
   (human small, 4 frames, occlusion, seed 0; methods/NOTES.md): D1 / D2 31.21 / 39.78 -> 38.77 /
   41.34 dB (no fill 28.66 / 41.04, lozes-pde 34.23 / 40.26). Medium region holes (a full disc of
   radius 5-11 spacings emptied) do not close within 3 rounds and are filled as in version 3.
2. Candidates: every frame g with 0 < |g - f| <= ``window``, nearest first (f-1, f+1, f-2, ...).
   Coverage test first: when one of g's own hole regions (moved to frame f by the motion of the
   frame one step nearer) comes within R's rim (centre distance < r + r_g + shell), g lacks part of
   the patch and its rim is holed (coherent holes drift by less than a hole per frame), so g is no
   full source: it is aligned the same way, and what it saw of R is used in step 5b only. The others
   are motion-compensated to f:
   a. rigid: g's points within ``r + 2 shell`` of where R lies in g (under the motion of the frame
      one step nearer to f, so a far frame starts from the chained motion) are aligned onto frame
      f's points near R by point-to-point ICP of g's shell (`methods.reference.icp_align`, open3d;
      3 rounds, the shell re-selected where g's points land, so g's own patch inside R never pairs
      with f's rim), then refined (``refine``) by point-to-plane ICP with pairs within 2 s
      (`refine_point_to_plane`: our own, `_point_to_plane.point_to_plane_icp`; open3d's sums its
      normal equations in a thread-parallel order, and version 4, which used it, gave a different
      fill from run to run), kept when the rim residual does not grow;
   a'. coarse to fine (``coarse_retry``, version 41): when the motion of a. misses b.'s bound, g is aligned once
      more from the same start, its ICP pairs first within the crop's reach (r + 2 shell), then within half of
      that, halving down to the shell, then 3 rounds within the shell as in a., g's crop taken again before each
      round round where R lies in g under that round's motion. The retry is kept when it puts R's place in g
      farther than the shell from where the start put it (within the shell the first alignment could reach the
      patch: a lower residual there is one more local minimum of an alignment that failed; samba 10-19, seed 5,
      frame 17: f+1's first alignment diverged 10 units, the retry came back 1.8 units from the start at 0.94 s,
      just under b.'s bound, and its copy, pooled with f-1's, displaced f-2's and f-3's at 0.44-0.45 s: D1
      29.77 -> 28.55 dB in that frame) and its rim residual is the lower; b. judges it.
      A frame with its own hole near R (the coverage test) keeps its first alignment, and its coarse motion, when
      within b.'s bound, only starts the alignment of the frames beyond it. Why: a limb that moved farther than
      the shell between two frames (a fast motion, a low frame rate) leaves ICP with pairs within the shell
      short of it, and g's crop round R's place in f holds only part of the patch (human small, "dance" motion,
      independent holes, seed 1, frame 0: a hole whose f+1 and f+2 rim residuals were 1.83 and 3.71 s, the hole
      left 88 % open; retried, 0.83 and 0.50 s, f+1's motion starting f+2's, the copy of f+2 covers it). Taken as
      the own-hole frame's motion too, it let f-1 carry a poor fill of a waving hand on through frames 6-9
      (human small "wave", coherent holes, seed 1: D2 23.97 -> 21.46 dB; the fill 1.0 -> 4.1 s off the truth at
      p90 in frame 6). An alignment that passes b. at once is not retried, so its result is unchanged;
   b. accepted when the trimmed mean rim residual is at most ``accept_spacings * s`` (two samplings
      of one surface lie about half a spacing apart; a wrong match lies a spacing or more off).
      Version 23: f-1 with its own hole near R that fails this bound is judged again on the rim
      points it saw (`seen_rim_residual`: those whose place in f-1 lies outside f-1's holes; a rim
      point where f-1 has a hole has no counterpart and measures the hole, not the motion); within the
      same bound there, its motion carries f-1's fill (step 5), and f-1 is still no source (nor a
      partial one: step 5b's agreement is widened by the whole rim's residual). Measured (one-off
      row runs, 10 frames, D1 / D2): D-FAUST coherent seed 3 22.51 / 30.25 -> 24.25 / 30.87 (a hand
      hole whose reused fill was lost at frame 4, f-1's whole-rim residual 1.07 s, then 1.25 s), seed
      2 21.58 / 31.54 -> 21.53 / 32.07; the other coherent and independent rows (4 sequences,
      seeds 0-2) within 0.05 dB. Grids: D-FAUST coherent, held-out seeds 3-4, 24.79 / 30.46 -> 25.67
      / 30.77; seeds 0-2 25.75 / 31.65 -> 25.73 / 31.83 (methods/NOTES.md "version 23");
   c. non-rigid (``deform``): each rim point q pairs with its nearest moved source point p within
      ``2 s`` and gives the normal residual v_q = ((q - p) . n_p) n_p (n_p: PCA normal of p's 10
      nearest source points); every candidate point inside R moves by the inverse-square-distance
      weighted mean of v over its ``deform_neighbours`` nearest rim points (Shepard interpolation
      of the rim's displacement field into the hole: where the surface bends between the frames,
      the rigid copy is bent with it). The candidate is g's moved points inside R.
   Version 28 (``adjacent_first``): frames beyond f+-1 are aligned only when f-1 and f+1 are not both
   sources. Where both saw R, a farther frame adds a copy that moved more (the reason step 4b pools only
   the adjacent copies) and costs as much again to align: skipping them more than halves the 800k-point
   benchmark (CPU 10.4 / 11.5 -> 4.5 / 5.0 s, versions 26 and 28 alternated on one machine) and moved the
   independent rows' D1 by -0.11 (bunny small), +0.05 (D-FAUST), +0.04 (human small), -0.04 (samba) dB
   (10 frames, seeds 0-2; held-out seeds 3-4: -0.08, -0.01, -0.04, -0.03; methods/NOTES.md "version 28");
   the coherent and occlusion rows, where f-1 and f+1 have their own hole, are unchanged. A farther frame
   with a lower rim residual than both adjacent ones is no longer found (samba seed 1: 2 of 40 holes).
3. Fusion, per part of the hole: candidates in order of rim residual (the best-agreeing frame
   first; equal residuals: the nearer frame). The first contributes its points farther than
   ``gap_spacings * s`` from frame f's points (a partially emptied region is not filled twice).
   Every candidate passed the coverage test, so its frame saw all of R: what its copy leaves open
   is its own sampling (gaps of 1-2 s between the samples of one surface) or surface its camera did
   not capture. Each later candidate therefore contributes only its points farther than the rim
   shell (``shell``, step 1) from everything accepted so far: the parts of the hole that the better
   frames did not see, which are hole-sized, not sampling gaps. Version 5 took the points farther
   than ``fill_gap_spacings * s`` (1 s): they were second layers 1-2 s off the first copy (the fill
   held 1.04-1.05 times the true point count) and, from badly aligned far frames (rim residual 0.97 s,
   2 s off the truth), misplaced patches. Measured (5 frames, medium independent holes, seed 0), D1
   with no later candidate at all against version 5: human small 28.67 / 26.77, bunny small
   35.83 / 35.46, D-FAUST 39.32 / 36.81, samba 33.45 / 32.94 dB (temporal-copy 27.48, 35.71, 37.57,
   31.59): the later points cost up to 2.5 dB and gained no coverage (0.999 / 0.999 of the true
   points within 1 s on human).
   When a candidate was accepted for R, the spatial fill (step 6) does not run for R either: its frame
   saw all of R, so the gaps its copy leaves are gaps of the capture (a scan's own holes), which the
   truth of frame f shares. Measured (D-FAUST punching, 5 frames, medium independent holes, seed 0):
   D1 36.81 -> 38.50 dB without the spatial fill (the voxelized sequences: no change).
4. Agreement: a later candidate's points (after step 3) are grown from R's rim and the accepted
   points (`grown_agreeing`): each round judges the points with at least 3 support points within
   ``3 s``; those within ``accept_spacings * s`` of the local plane of their 8 nearest support points
   continue the surface and join the support, the others disagree with the better-aligned frames and
   are dropped; points that no chain of kept points reaches (a layer or patch floating in the hole)
   are dropped too. Version 5 judged against the accepted points only, once, and kept the points with
   no accepted point within 3 s: the misplaced patches were such points.
4b. Re-voxelized copies (``revoxelize``, voxelized input): the fused copies (steps 3-4) sit at sub-voxel
   positions after the motion compensation, and rounding each to its nearest voxel put 7-19 % of
   them one voxel off the true ones (methods/NOTES.md). Instead the copied surface is voxelized by the
   capture's own rule (`surface_voxels`): every free voxel c inside R within one voxel edge of a copied
   point (`COPY_REACH`, version 37; sqrt 3 before) is
   kept when the MLS quadric of its ``mls_neighbours`` nearest points (frame f near R and the copies)
   passes close enough to c's cube, |(c - p) . n| <= t (|n_x| + |n_y| + |n_z|) / 2, where t = 1 is every
   cube the surface crosses. Captures voxelize more or less thickly (all crossed cubes; or the cubes
   their samples fell in, fewer where a cube is only clipped), so t is read from the frame, per hole
   (`rim_crossing_threshold`): the t that best separates R's rim voxels (occupied) from the free voxels
   next to them outside R under the same fit. Measured (10 frames, medium independent holes, seeds
   0-2, D1 / D2 means, version 7 -> 8): bunny small 35.63 / 39.12 -> 36.53 / 40.91, human small
   28.65 / 31.91 -> 29.70 / 33.34, samba 32.97 / 37.03 -> 33.05 / 37.43; coherent (seed 0, 10 frames)
   and occlusion rows (seed 0, 5 frames) unchanged; D-FAUST is not voxelized (step 4b does not run).
   Version 9 re-voxelizes the reused fill of step 5 by the same rule (step 7; it too lies at sub-voxel
   positions, moved by f-1's motion), where version 8 rounded it: coherent holes, 10 frames, seeds 0-2,
   D1 / D2 means, 8 -> 9: human small 19.02 / 26.55 -> 20.11 / 27.05, bunny small 28.54 / 35.61 ->
   30.31 / 36.73, samba 17.80 / 27.11 -> 18.02 / 27.27; independent rows within 0.01 dB (seed 0),
   human occlusion 46.98 -> 47.12 (seed 0, 5 frames).
   Version 26 (``pool_adjacent``): the fit's support also holds the copies of f-1 and f+1 where they were
   sources (step 3) other than the one fused first, and the fit takes ``mls_neighbours`` points a copy (28 on
   voxelized input: the same disc of 3 s, each copy's points in it). Each adjacent copy is another capture of
   R's surface, aligned on its own, and the copies' alignment errors, not the voxel rounding, are what is left
   of the independent rows' error (methods/NOTES.md "version 17": 0.18 voxel RMS on samba); a fit through
   several copies averages them. Only f-1 and f+1: frames farther off moved more, and with every source
   pooled samba independent (seed 0) lost (33.71 -> 33.32 D1) where f-1 and f+1 alone gained (-> 34.11).
   Coherent holes leave f-1 and f+1 no sources there (their own hole is near R): those rows are unchanged.
   Grid, version 25 -> 26 (10 frames, D1 / D2 means; methods/NOTES.md "version 26"): independent holes, seeds
   0-2, bunny small 37.02 / 41.09 -> 37.95 / 42.21, human small 29.92 / 33.49 -> 30.52 / 34.15, samba 33.24 /
   37.43 -> 33.55 / 37.82; held-out seeds 3-4 37.39 -> 37.75, 29.86 -> 30.33, 33.12 -> 33.23 (D1); every
   coherent and occlusion row and D-FAUST (not voxelized) unchanged. Cost: about 1.4 s CPU of ~10 at 800k
   points with 5 holes (the 56-point fits).
   Version 31 (``count_copies``): the copies' own count of voxels is kept, the candidates with the smallest
   offsets (`surface_voxels`' ``count``), in place of the bound t. The copies are the same capture's voxelization
   of the same surface, so their count is the count to expect; t is read where frame f's own fit judges its own
   voxels, and a fit through aligned copies judges the hole's candidates with a wider scatter, so the same t kept
   too few or too many: samba independent holes (seed 2 frames 0 and 9, seed 1 frames 4, 5, 8; one-off per-hole
   attribution) got 3-8 % fewer voxels than the truth in most holes, truth-to-result error above result-to-truth
   (D1 takes the larger), where temporal-copy's rounded copy matched the count; human small's got 2-7 % more. On
   a thin capture (a sampled sphere, the test) t is unsteady and kept as few as 9 % of the count. Keeping at
   least the count (t a floor) gained samba and bunny as much and lost human small 0.11 dB D1. Grid, version 30 ->
   31 (10 frames, seeds 0-2, D1 / D2; methods/NOTES.md "version 31"): independent holes, samba 33.51 / 37.79 ->
   34.06 / 38.34 (temporal-copy 32.84: +1.22 dB), bunny small 37.84 / 42.10 -> 38.17 / 42.27, human small 30.56 /
   34.22 -> 30.78 / 34.44; every coherent and occlusion row and D-FAUST (not voxelized) unchanged. Held-out seeds 3-4: samba 33.20 -> 33.85, bunny
   37.67 -> 38.20, human 30.29 -> 30.46 (D1); MVUB ricardo9 (a real capture, 2 frames, seed 0) 35.30 / 37.51 ->
   35.45 / 37.66.
5. Reuse (``reuse_previous``): the points frame f-1's result added (copies, reused and spatial
   fill alike, steps 5b, 6d and 6e excepted) are moved to frame f by f-1's motion (steps 2a and 2c,
   computed even when f-1 failed the coverage test; accepted by step 2b, on the rim f-1 saw) and,
   where they still fit the rim (points within 3 s of the rim and farther than ``accept_spacings * s``
   off its local plane are dropped, as in step 4), fill the parts of R that the copies left open.
   They *replace* the spatial fill there (step 6 fills only what is still open), so fills never pile
   up, and a persistent hole keeps the fill it had, moved with the body.
5b. Partial sources (``partial_sources``): the frames that failed the coverage test only because of their
   own hole near R (aligned and accepted as in step 2) saw part of R. Their points inside R, best rim
   residual first, fill what is still open after steps 3-5: farther than ``fill_gap_spacings * s`` from
   every point accepted so far, and through step 4's agreement (grown from the rim and the accepted
   points), its tolerance widened by the copy's own rim residual (version 18: such a copy, aligned on a
   rim its own hole cuts, sits up to that residual off the rim's surface next to it, and step 4's 1 s
   alone dropped the first ring of points and with it every point behind them: MVUB ricardo9, a real
   capture held out from tuning, independent holes seed 1, one box kept 268 of 699 points lying as close
   to the truth as the kept ones, 0.18 / 0.92 s p50 / p90). Step 7 treats them as it treats reused points (projected onto the surface, re-voxelized by
   step 4b's rule on voxelized data: unprojected, 9-15 % of them lay 1.5-4 voxels off the truth on human
   small coherent holes, beside the reused fill), and step 5 does not reuse them: moved on by each
   frame's motion and topped up by the next frame's, they piled up in persistent occlusion boxes (samba
   occlusion, 10 frames: D2 26.4 in frame 0 down to 13.6 in frame 9). The spatial steps (6-6e) still
   run where no full candidate was accepted, on what is left open. Why: occlusion holes sit in every
   frame at nearly the same place (armpits, crotch, soles), so the coverage test dropped every source
   there, while the body's motion shows part of each box to the neighbours. Measured (targets grid, 10
   frames, seeds 0-2 where the row has them, D1 / D2, version 15 -> 16; methods/NOTES.md "version 16"):
   D-FAUST occlusion 23.71 / 35.98 -> 26.07 / 36.15, samba occlusion 11.32 / 27.55 -> 14.78 / 27.25, human
   small occlusion 48.56 / 51.18 -> 63.74 / 66.39, D-FAUST coherent 25.26 / 31.04 -> 25.78 / 31.71; the
   other rows within -0.15 / +0.5 dB.
6. Spatial fill, only where no frame saw the surface and nothing was reused, and only where it can be
   put on the surface with confidence (`rim_surface_fill`): the support is R's rim plus the copied
   points; its PCA frame (u, v, n) must make it a height field (at most ``MAX_STEEP`` = 1/4 of the
   support's normals more than 60 degrees off n); a thin-plate spline h(u, v) (in units of s,
   smoothing 1, quadratic polynomial part) is fitted to the support; hold-out test: the spline of the
   outer rim alone (farther than shell / 2 from R) must predict the inner rim's heights with RMS error
   at most ``surface_holdout_spacings * s``, since the inner ring is as far from the outer rim as the
   hole's edge. Grid points (step s, s / 2 on voxelized data, then rounded to the voxels the surface
   passes through; on unvoxelized data the step is 1 / sqrt(areal density), `lozes_pde.sampling_step`,
   so the fill has the data's density; version 5 used the median nearest-neighbour distance, about half
   that on an uneven sampling, and put 10,025 points where 7,056 were missing on D-FAUST coherent
   holes, 4 frames, seed 0, against 2,307 now with the same D1) inside the convex hull of the support's (u, v) (interpolation,
   never extrapolation), inside R and farther than ``fill_gap_spacings * s`` from every point are
   lifted onto the spline. A hole that fails a test goes to step 6f, then 6c (with those off it stays
   open: an off-surface fill costs more in D2 than an open hole, as step 6b measured).
6c. Closed-surface fill (``poisson``, on by default; `poisson_surface_fill`): where step 6 added nothing
   (its tests refused the hole: a hole round a limb, a neck or a foot, or one that cuts a limb through), on
   what step 6f left open,
   the crop of step 1 and the reused points are reconstructed by screened Poisson (open3d, one thread;
   PCA normals oriented along the surface by a spanning tree, `orient_along_surface`, each connected part
   of the tree with the sign that points most of its normals away from the crop's centroid, which lies
   inside a limb), on an octree whose
   finest cell is the fill's grid step (depth = ceil(log2(1.1 extent / step)): the same surface detail
   at every density); the surface is sampled at half a step, rounded to voxels on voxelized data (else
   one sample a cell), and the points inside R, free, and attached to the captured surface (chains of
   points with 3 support or kept points within 3 s) are R's fill, when step 6's hold-out test passes
   (the surface of the crop without its inner ring, shell / 2 wide, misses that ring by at most
   ``surface_holdout_spacings`` s RMS: a reconstruction from misoriented normals, or of a sharp edge
   such as a sole at the floor, fails it), less in quadrature the ring's own scatter (its RMS distance to the
   surface of the whole crop; version 21): a noisy capture misses any smooth surface by its noise, held out
   or not. Measured (MVUB ricardo9, a real capture held out from tuning, coherent holes): the ring's scatter is
   0.5 s there (0.1-0.2 s on D-FAUST), and a hole whose Poisson fill lay 0.64 s off the truth was refused
   at a miss of 1.12 s (0.99 less the scatter). Grids (methods/NOTES.md, "version 21"): ricardo9 coherent
   25.59 / 34.62 -> 27.78 / 34.77 (lozes-pde 27.26 / 31.76), bunny small coherent 33.25 / 36.22 -> 34.04 /
   37.30; every other row within 0.1 dB. Each body of the crop (``poisson_bodies``: its connected
   components, points linked within 3 s, the attachment reach; those with at least 32 points and a point
   within 3 s of R) is reconstructed and tested on its own, and the fill is the union.
   Why bodies (version 13): one reconstruction of a crop holding two bodies closer than the hole's
   diameter (a thigh above a forearm, a hand at the hip) closes the indicator function across the gap
   between them inside R, a bridge that the hold-out ring does not see: samba coherent seed 1 (10 frames),
   a fill 1.4 / 4.1 voxels off the truth (p50 / p90) passed the hold-out at 0.91 s and, reused over the
   frames, took whole-frame D2 from 26.20 (no step 6c) to 16.95 dB; body by body the row gives D1 / D2
   25.60 / 28.27 (no fill 9.00 / 26.24). Rows: methods/NOTES.md, "version 13".
   Except the two ends of a limb that the hole cuts through (version 22; ``poisson_bridges``, `limb_ends`):
   bodies whose points next to R lie to one side of its centre (their mean unit direction from it at least
   0.5 long; round a patch the body's surface encloses it is about 0, at the cut end of a tube of radius a
   through a ball of radius r about sqrt(1 - (a / r)^2)), paired when they point apart. Body by body each end
   was capped and the limb between left open; one Poisson surface of the two caps each short piece rather
   than span a gap longer than its diameter. A pair is filled by step 6's spline in the tube's chart
   (`tube_fill`: the radius over the axial position and the arc length round the axis through the two ends'
   centroids, with step 6's normal, hold-out and interpolation tests in that chart) and, refused, body by
   body as before. Measured (samba coherent, seed 0, 10 frames: an arm cut through at the elbow; row.py):
   D1 / D2 18.68 / 22.72 -> 24.09 / 25.97. Grids (methods/NOTES.md "version 22"): targets (seeds 0-2) samba
   coherent 23.57 / 26.58 -> 25.58 / 27.99 (no fill 9.02 / 27.84: D2 above no fill now), held-out seeds 3-4
   bunny coherent 34.17 / 37.41 -> 34.14 / 37.39, every other row and the held-out data unchanged.
   In a region that keeps captured points (an occlusion box) the hold-out's ring takes in the data kept inside
   the box too, so the test judges a surface across the whole box, which the fill never spans: most boxes are
   refused there, at most of the run's time (``poisson_in_boxes=False`` skips step 6c in them; kept on by
   default: its fills in boxes, carried on by step 5, measured better over the frames after them than step 6e's
   membrane, which is not reused: methods/NOTES.md, "poisson_in_boxes").
   Why step 6c at all: a hole left open costs whole-frame
   D1 in proportion to its radius in voxels, so the same holes cost 7.8 dB more at default size (radius
   26.7 voxels) than at small (10.9): human coherent holes seed 1, 2 frames, all three refused by step 6:
   D1 / D2 8.78 / 26.95 dB open at small, 1.21 / 21.97 open at default; medium holes land on a limb about
   half the time. Human default, coherent, 10 frames, seeds 0-2 (methods/NOTES.md): D1 / D2 3.20 / 22.69
   (version 7) -> 22.11 / 25.41 (no fill 1.43 / 22.11, temporal-graph 16.26 / 19.24).
6d. Cap (``cap``, voxelized input; `cap_fill`): where steps 6 and 6c (6 alone where the loop is walled, below)
   added nothing, an opening that no surface round it continues (the base of a body standing on the floor, a
   sole, a crown above the cameras) is spanned by a membrane across its boundary loop: the points of frame f within
   2 s of R, whose heights over their own plane must have an RMS of at most max(1 s, r / 20) (two rims of
   a band round a limb, or a rim bent round a fold, lie at different heights and are refused; on a large
   opening the cap's error is of the loop's wobble, far less than the distance of the missing points to
   the rim, which grows with r). Version 29 (``harmonic_cap``): the membrane is the harmonic height field
   over the loop's plane (`harmonic_height_field`: a grid of step 6's step, the cells the loop's points fall
   in fixed at their mean height, the others inside the loop's convex hull solving Laplace's equation), with
   the loop's points on steep walls left out (their normal more than 60 degrees off the plane's normal,
   step 6's angle, `_flat_anchors`: a grid cell over a wall would take the mean of its column). By the maximum
   principle the cap stays within the heights of the loop. Up to version 28 it was step 6's thin-plate
   spline through the loop (linear polynomial part, no normals test), the least-bending plate, which
   continues the slope the loop has where it leaves the walls: the bunny's base (a 150-voxel opening whose
   rim rises from the body's walls and whose middle is hollow) got a cap 2-3 voxels above the rim that left
   the box, so its middle stayed open. Its points are rounded to voxels. Since version 29 not reused by step 5
   (as step 6e's membrane): frame f + 1 spans its own loop, where the moved cap's points drifted (the bunny base's
   farthest fill point from the truth grew from 7 to 14 voxels over 10 frames); the thin plate, which left the
   middle open, needed the earlier frames' caps there. Voxelized input only: rounded to the
   capture's voxels, a cap within half a voxel of the surface is exact, while on D-FAUST (unvoxelized) the
   version-13 caps lay 0.55 s RMS off the true surface (5 frames, occlusion, frame 0) and the whole-frame D2
   dropped 0.21 dB for +0.33 dB D1.
   Measured (version 13, occlusion holes, seed 0, 5 frames, D1 / D2): bunny small -7.68 / 2.61 -> 1.05 / 4.61
   (fu-nonlocal -2.22 / 7.42), samba 11.06 / 28.17 -> 11.09 / 28.21, human small unchanged. Version 28 -> 29
   (10 frames, D1 / D2 / NSHD x 1e9; methods/NOTES.md "version 29"): bunny small occlusion 1.84 / 4.33 / 34.7 -> 6.18 /
   6.71 / 5.52 (fu-nonlocal -1.98 / 7.66 / 79.3), samba occlusion 21.09 / 28.36 / 1.13 -> 21.06 / 28.31 / 1.16; every
   other row unchanged.
   Version 30 (``walled_cap_first``): step 6d goes before 6c where walls rise from the opening (`cap_walled`: more
   than a quarter of the loop's points have normals more than 60 degrees off the loop's normal, step 6's
   height-field test, failed): no surface round such an opening continues over it, so 6c's closed surface has no
   side of it to follow and its hold-out refused every one measured (the bunny's base, 33-35 % steep: 15 screened
   Poisson reconstructions, 83 % of a 635k-point frame's CPU, for nothing). Where a surface round the hole goes
   on over it (the bunny's coherent holes that 6c fills, 0-9 % steep) 6c keeps its turn: capped first those lost
   1.07 dB D1 (seed 2), and a bound on the membrane's sag (`membrane_sag`) does not tell them apart (0.2-0.95 s
   there, 13 s at the base, whose loop rises up the walls).
   Version 35: and only where the region is shallow past the loop's plane (it reaches past it, on the side away
   from the data, by at most the loop's radius; `cap_walled`): a closed end of the walls (a hand past a wrist) is
   round and reaches about that far, so a deeper region may hide one, which 6c's closed surface follows and the
   flat cap does not. The 800k human's coherent hole over a hand (57 voxels past a wrist loop of radius 15), capped
   first: 559 points 6.2 voxels RMS off the truth; 6c first: 1,104 points 0.94 off.
   Grids (methods/NOTES.md "version 30"): every row of the targets (seeds 0-2) and held-out (3-4) grids unchanged,
   bunny small occlusion 272.7 -> 99.8 s CPU for its 10 frames; at paper scale (bunny-635k, occlusion, 2 frames,
   the benchmark) 256.6 -> 91.4 s.
6e. Membrane (``membrane``; `membrane_fill`): where steps 6-6d added nothing, the open parts of R are spanned by
   `lozes_pde.LozesPDE`'s harmonic graph fill (p = 2) anchored at every point of frame f and of the accepted
   points within 3 grid steps of R, inside R included: seeds on the anchors' PCA plane where no anchor
   projects within 0.8 step, each moved to the weighted mean of its 10 graph neighbours, anchors fixed. It is
   made for occlusion boxes, which keep captured points inside (60-1,200 in each D-FAUST box: an armpit, the
   crotch, a sole): there the membrane interpolates between data a few spacings apart, while steps 6-6c
   extrapolate the rim round the box and their hold-out tests refuse. Four tests, each a rule used above:
   step 6's height-field test over the plane the seeds lie on (at most half the anchors' normals more than 60
   degrees off its normal; version 20: samba's widest box, wrapped round the body with 55 % of them steep, got a
   membrane 2 s off the truth that the other tests passed);
   interpolation only (seeds inside the convex hull of frame f's points inside R, as step 6's grid), unless
   the anchors' quadric says the membrane cannot sag far from the surface (`membrane_sag`: the harmonic
   membrane departs from a quadric h by |c3 + c5| r^2 / 2 at the centre of a disc of radius r, and that must be
   within ``surface_holdout_spacings`` s; version 19; since version 34 r is the widest open disc among the
   anchors, `_open_radius`, not R's radius: a box keeps data inside, and its gaps are far narrower than it). So an emptied disc on a flat or saddle-shaped
   patch is spanned, one round a limb is not (there the membrane lies 2 s inside the surface, the sag
   1.5 s, and the other tests pass it); step 6's hold-out with its bound (the anchors within 1.5 steps
   of the open part's edge are left out, and the membrane of the others must predict them to
   ``surface_holdout_spacings`` s RMS; up to version 19 the band was round R, so all the box's inside data
   was left out and the test judged a membrane across the whole box, which the fill never spans: it
   refused D-FAUST boxes whose fills lay 0.26 s off the truth); step 4's agreement (`grown_agreeing`: grown
   from the anchors, each point within ``accept_spacings`` s of their local plane, and not between two
   layers of them, `between_layers`: two surfaces in one box). Why the agreement (D-FAUST occlusion, 10
   frames, seed 0, the 39 fills the hold-out passed, each scored against the true frame): it let through a box at a fold (an
   armpit, frames 4-7) whose membrane lay 1.1-1.8 s RMS off the truth and cost up to 1.9 dB of whole-frame
   D2; the agreement rule cut it to 3-11 points 0.2-0.9 s off and kept 60-100 % of the other fills at the
   same accuracy (0.06-0.6 s). Not reused by step 5: the membrane rests on frame f's own data inside the
   box, so frame f + 1 builds its own (reused, moved by f-1's motion, it cost 1.9 dB D2 over 5 frames).
   Measured (targets grid, 10 frames, D1 / D2; methods/NOTES.md "version 15"): D-FAUST occlusion 20.10 /
   35.12 -> 23.71 / 35.98 (no fill 19.30 / 35.51, lozes-pde 27.35 / 33.46); every other row unchanged.
   Version 19 (open discs within the sag bound; NOTES "version 19"): D-FAUST occlusion 26.19 / 36.03 -> 26.71 /
   35.95; held out: ricardo9 coherent 24.36 / 34.36 -> 25.59 / 34.62 (a disc beside a fold of the shirt, which
   steps 6-6c refuse), D-FAUST coherent seeds 3-4 24.57 / 30.51 -> 24.79 / 30.45; every other row unchanged.
   Version 20 (the hold-out band round the open part, the height-field and two-layer tests; NOTES "version 20"):
   D-FAUST occlusion 26.71 / 35.95 -> 28.53 / 35.76 (lozes-pde 27.35 / 33.46), samba occlusion 14.84 / 27.35
   -> 15.26 / 27.70 (no fill 27.44); every other row within 0.03 dB.
   Version 24 (on the hole's sheet; `_flat_anchors`, `_sheet_bounded`): a box whose anchors fail the height-field
   test because a second surface crosses the hole's sheet (legs through the sheet that closes a skirt at its hem:
   samba's widest box, refused by that test since version 20) is spanned on its sheet: the anchors whose normal is
   within 60 degrees of their plane's normal (the test's angle, point by point) anchor the membrane; it is seeded
   where no point of either surface projects within the seed gap, and an open part of that footprint is kept when
   at least half of its seeds lie nearer (on the plane) to a sheet anchor than to the crossing surface (the inside
   of a tube through the sheet borders the tube's wall alone); the four tests then judge the sheet's membrane.
   Measured (targets grid, 10 frames, D1 / D2; methods/NOTES.md "version 24"): samba occlusion 15.26 / 27.70 ->
   21.15 / 28.46 (lozes-pde 15.33 / 16.12, temporal-copy 12.01 / 27.78; the hem box's fill 0.42-0.55 voxel RMS off
   the truth); every other row, the held-out seeds and the held-out data unchanged.
   Version 33 (``partial``): step 5b's copies anchor the membrane too, where the frame's own and the accepted
   anchors pass the height-field test without them (a copy of one side of a box must not make a box wrapped round
   a limb look flat: samba's hem box, 54 % steep, 50 % with its copies, got a membrane 2.3 s RMS off the truth).
   Measured (targets grid, D1 / D2 / NSHD 1e-9; NOTES "versions 32-34"): D-FAUST occlusion 28.58 / 35.75 / 0.88 ->
   28.92 / 35.93 / 0.70, samba occlusion 21.06 / 28.31 -> 21.09 / 28.06; held-out frames, D-FAUST occlusion 26.18 /
   33.75 / 1.20 -> 26.43 / 33.72 / 1.09; every other row unchanged. Version 34 (`_open_radius`, the sag over the
   widest open disc among the anchors): D-FAUST occlusion 28.92 / 35.93 / 0.70 -> 29.42 / 35.88 / 0.56 (lozes-pde
   27.35 / 33.46 / 0.84); held-out frames 26.43 / 33.72 / 1.09 -> 27.29 / 33.85 / 0.68 (lozes-pde 25.97 / 31.75 /
   0.72); D-FAUST coherent seed 0 28.52 / 31.72 -> 28.75 / 31.61; every other row within 0.03 dB.
   Version 42 (``membrane_after_poisson``): in a region that keeps captured points, what step 6c filled no longer
   ends step 6 there: the membrane spans what it left open, its points among the anchors and counted as covered,
   and both are kept (step 6c's part reused by step 5 as before, the membrane's not). In a box step 6c passes only
   a few points (its hold-out judges a surface across the whole box, see 6c), and those took the whole box from
   the membrane: D-FAUST occlusion frame 2, fills of 6 and 4 points in boxes with 312 and 99 hidden points. In an
   emptied region step 6c's fill still ends step 6 (the membrane after it was measured there at version 22: a
   trade of D1 for D2 on the hands of D-FAUST coherent holes, methods/NOTES.md). Measured (occlusion rows,
   D1 / D2 / NSHD 1e-9; NOTES "version 42"): D-FAUST 29.34 / 36.17 / 0.554 -> 29.50 / 36.19 / 0.514, at half
   the frame rate 28.35 / 34.90 / 0.736 -> 28.45 / 34.89 / 0.692 (lozes-pde's NSHD 0.726); every other row
   within 0.01 dB.
6f. Sheet (``sheet``; `rim_sheet`): where step 6 refused the hole, it is tried again on the hole's own sheet
   of its support: the points whose normal is within 60 degrees of the inner ring's normal axis (the support
   within shell / 2 of R: the surface at the hole's edge), and of those the part connected by links of 3 s to
   the most inner-ring points; only when that edge is one sheet (mean squared cosine of the inner ring's
   normals to their axis at least `SHEET_MIN_ALIGNMENT` = cos^2 30 degrees: a 90-degree fold gives 0.5, a
   ring over 120 degrees of a limb's arc 0.71). Step 6's tests (height field, hold-out, convex hull) then
   judge the sheet alone. What its fill leaves open stays open for steps 6c-6e (their support is unchanged;
   the sheet's fill counts as covered). Why: a hole's crop reaches r / 2 past its edge, and where a second
   surface stands within that (an arm against the chest, the torso where a limb leaves it) step 6's normal
   test refused the whole crop while the hole itself lay on a flat patch; step 6c's closed surface, or
   nothing, filled it. Found on seeds held out from those the defaults were judged on (D-FAUST, region
   seeds 3 and 4, 10 frames; methods/NOTES.md "version 17"): coherent holes D1 21.95 -> 24.53 (fu-nonlocal
   24.76; seed 4 alone 21.91 -> 27.08), independent 39.75 -> 40.14; the targets grid (seeds 0-2) unchanged
   but for bunny coherent (D1 / D2 32.98 / 35.83 -> 33.17 / 36.14). Without the one-sheet test the retry
   filled across a fold on samba coherent (seed 1) and the reused fill drifted into a flap (frames 7-9:
   D1 25.8 -> 20.4).
6b. Advancing front (``front``, off by default): where steps 6 and 6c added nothing (its tests refused the
   hole, e.g. a hole round a limb, which is no height field over one plane), the open cells of R are
   grown from the rim and the copies one cell shell a round (`_front_fill.front_fill`; cell 1 voxel,
   or s on unvoxelized data): a free cell within sqrt 3 cells of the trusted points is accepted when
   the MLS quadric of its ``mls_neighbours`` nearest trusted points crosses it (step 1b's rule) and
   that fit's weighted RMS residual is at most the 90th percentile of the same fit's residual at the
   rim's own points (a fit over two layers, where fronts meet at different heights, is refused).
   At most ceil(sqrt(k / pi)) rounds (step 1b's fit radius), so no new point lies farther than one
   fit radius from captured points; unlike step 1b the growth need not close, so a wide hole gets
   a band along its rim. New points: the voxel, or the foot point on the quadric. Off by default:
   measured (methods/NOTES.md, "step 6b") it raises D1 by 6-8 dB on D-FAUST coherent and occlusion
   holes but lowers D2 by 0.9-2.2 dB below no fill there (the metric's point-to-plane error of a fill
   0.3-0.8 s off the surface costs more than an open hole), which the issue forbids.
7. Surface projection of the copies and reused points (then, on voxelized data, the reused points are
   re-voxelized as in step 4b): every such new point (on voxelized data: the
   reused ones only; copies are voxels of a captured surface already) is moved onto a moving-least-squares
   surface of its neighbourhood (frame f's points near R and the new points): the ``mls_neighbours`` nearest
   support points, a PCA frame at their centroid, a least-squares quadric height field
   h(u, v) = c0 + c1 u + c2 v + c3 u^2 + c4 u v + c5 v^2 (Gaussian weights, bandwidth the distance
   to the farthest neighbour / 2), and the point replaced by (u, v, h(u, v)).
7b. No second layer over the captured surface (``drop_layers``, version 39), in a region that keeps captured
   points inside (an occlusion box; a region hole the generators punch, or a hole found blind, is emptied, so
   only its rim lies inside): a new point is dropped when the captured points round it (its 16 nearest within
   2 s, at least 3) surround it, |mean of the unit tangential directions to them| < 0.5 (at a hole's edge they
   all lie to one side, near 1), and it lies farther than ``FLOAT_LAYER_SPACINGS`` (0.5 s) off their PCA
   plane; on voxelized input (version 40) a voxel whose cube the plane of the 50 captured voxels within 4 does not
   cross (`VOXEL_LAYER_REACH`, `VOXEL_LAYER_NEIGHBOURS`). Such a point lies over surface the frame
   captured, as a layer beside it: a copy misaligned there, where step 3's 0.5 s test only removes what lies
   on the captured points. Why: on D-FAUST's occlusion boxes at half the frame rate a box with 411 hidden
   points got 1,014 fill points, 460 of them more than 4 s from every hidden point and 1.3-2.2 s off the
   truth (methods/NOTES.md "half the capture's frame rate"). On voxelized input a captured plane's staircase
   scatters up to half a cube diagonal about its plane, so a fixed bound off a small fit's plane cannot tell a
   layer from it (at 0.5 voxel the staircases of step 1b's gaps and step 4b's copies read as layers: human small
   occlusion 63.31 -> 47.35 D1; at 1 voxel the layers one voxel off pass); the plane-cube test over a disc of 4
   voxels does (`VOXEL_LAYER_REACH`). Measured (every occlusion row of the targets and held-out grids, D1 / D2;
   methods/NOTES.md "versions 39 and 40"): without step 7b -> with it, D-FAUST 29.42 / 35.89 -> 29.34 / 36.17,
   D-FAUST 10-16 27.29 / 33.84 -> 27.21 / 33.84, D-FAUST at half the frame rate 28.44 / 34.40 -> 28.35 / 34.89
   (no fill 34.42); version 39 -> 40 (the voxel rule), samba 21.03 / 28.14 -> 20.95 / 28.21, samba 10-19 21.44 /
   28.67 -> 21.24 / 29.05, samba at half the frame rate 21.25 / 27.46 -> 21.11 / 28.24 (no fill 27.54), human
   small 63.24 / 65.66 -> 62.77 / 66.89, bunny small unchanged.
8. Voxelized input (every coordinate an integer; ``snap="auto"``): all new points are rounded to the
   grid (half up), duplicates merged, and voxels that frame f already occupies dropped: one point per
   voxel, never on a captured one.
9. Back-fill (``reuse_next``, version 38): once every frame is filled, the frames are visited again from the
   last to the first. A hole R of frame f that steps 3-6 left open (nothing copied, reused or spatially filled;
   step 5b's partial copies may be there) takes what frame f+1 found in its own holes, moved back to frame f by
   frame f+1's motion to f (steps 2a-2c, computed while frame f was filled; f+1 with its own hole near R is
   judged on the rim it saw, as f-1 in step 2b), with step 5's tests (only where R is still open, and on the
   rim's surface) and step 7's treatment. What frame f+1 found: its copies, its spatial fills and what step 9
   gave it, not what it reused from frame f (frame f holds that already; carried there and back by two motions
   it lies beside it). Visited last to first, a fill found late in a persistent hole reaches every earlier frame.
   Why: step 5 carries a fill forward only, and the spatial steps' tests are decided on each frame's own rim, so
   a persistent hole refused in its first frames stayed open there while a later frame filled it. Found on frames
   held out from tuning (D-FAUST punching 10-16, coherent holes, seed 6): a hole across a forearm and the torso
   that step 6c's hold-out refused in frames 0 and 1 (1.04 and 1.19 s against its bound of 1) and passed in frame 2
   (0.55 s); frames 0-1 D1 / D2 18.44 / 25.98 and 18.59 / 26.18 -> 22.27 / 25.85 and 22.30 / 25.86. Only holes
   left open: carried into every hole where frame f+1 found more (human small coherent, seed 0, 10 frames), the
   moved points lay beside frame f's own fill, D1 / D2 27.06 / 29.12 -> 26.97 / 28.90 (24.60 / 25.89 with the
   points f+1 had reused from f carried back too).

Every step is vectorised over points; the per-hole work runs on crops of size O(r^2 / s^2), so the
time is linear in the points (one k-d tree per frame) and in the holes. Crops are taken in the frame's
point order (sorted ball queries), so the result does not depend on how a k-d tree is laid out.

Parameters, each with the rule it follows (no value was fitted to a sequence or a seed):
  window            3 frames: at 30 fps a hole's patch is seen again within +-0.1 s when it drifts
                    over the surface or the body turns, and farther frames deform too much for a
                    rim-driven correction.
  shell_factor, shell_spacings  0.5 r and 4 s: the rim must be wide enough to fix a rotation (a
                    ring of a few samples constrains only a translation) and narrow enough to move
                    with the hole's own part of the body (`temporal-copy`'s measured choice).
  icp_iterations    30: per ICP call (open3d stops earlier at convergence), as temporal-copy.
  refine            True: point-to-plane refinement (step 2a). Measured (one-off script, human tiny and
                    dfaust, 4 frames, medium independent holes seed 0, copies from f-1/f+1): RMS
                    distance from the true hidden points to the copy 0.54 -> 0.45 voxel (after
                    rounding) and 1.30 -> 1.10 units; pairs within 2 s, not the shell width: the
                    plane fit is only right where the samplings already overlap.
  accept_spacings   1.0 s: see step 2b.
  deform            True; deform_neighbours 32: enough rim residuals that a sample's own +-0.5 s
                    sampling offset averages out (1/sqrt(32) of it is left).
  gap_spacings      0.5 s: a copied point closer than half a spacing to a captured one duplicates it.
  fill_gap_spacings 1.0 s: a reused (step 5) or spatial-fill (step 6) point nearer than one spacing to
                    an accepted one samples the same surface element (up to version 5 also the gap a
                    later candidate filled; since version 6 that is the rim shell, step 3).
  reuse_previous    True: a persistent hole's surface is the same surface, moved (step 5). Version 1
                    had it off because reused and fresh points piled up (dfaust coherent 23.85 ->
                    19.08 dB); with replace-not-add (version 2) it is better on every figure, human
                    small coherent seed 0, 4 frames: D1 25.65 -> 26.02, D2 28.42 -> 29.49 dB, temporal
                    consistency 0.400 -> 0.293.
  fallback          True: the spatial fill of step 6 (False leaves what no frame saw open).
  surface_holdout_spacings  1.0 s: a surface that misses the rim's own inner ring by a spacing or more
                    is a wrong surface (the same rule as ``accept_spacings``). Seen (human small and
                    dfaust, medium coherent holes, seed 0, frame 0): hold-out 0.09-0.75 s where the
                    fill's true D2 RMS error was 0.18-0.61 s; 4.2 and 5.1 s where it was 1.3 and 2.0 s.
  mls_neighbours    "auto": 20, and 28 for the voxel decisions of steps 1b and 4b on voxelized input
                    (`FIT_NEIGHBOURS`, `VOXEL_FIT_NEIGHBOURS`; an integer sets every fit). A quadric has 6
                    coefficients; 20 points over-determine it ~3 times while spanning about 2.5 s, so on exact
                    surface samples the fit follows the surface, not the noise. Captured voxel centres are the
                    surface rounded by up to half a voxel on each axis, so where a fit decides which voxels a
                    captured surface crosses (the rim's in step 1b, the copies' in step 4b) it takes the points of
                    a disc of step 4's reach, 3 s: pi 3^2 ~ 28 (step 1b's round count, ceil(sqrt(k / pi)), stays
                    3). Step 7 keeps 20: inside a persistent hole its support is mostly the reused fill itself,
                    and with 28 there a fill's drift grew into a flap (human small coherent seed 3, held out,
                    frames 6-9: the fill 0.97 -> 2.02 s RMS off the truth, D1 25.09 -> 23.84 over 10 frames).
                    Measured (version 24 -> 25, 10 frames, D1; methods/NOTES.md "version 25"): samba
                    independent seed 0 33.59 -> 33.72, human small independent seed 0 29.62 -> 29.75, bunny small
                    independent seed 0 36.31 -> 36.87; coherent rows unchanged; D-FAUST (float) unchanged.
  rim_fill          True: step 1b (voxelized data only); its round count follows from mls_neighbours.
  poisson           True: step 6c; its octree depth and sampling follow from the grid step, its trust rule
                    from step 4's reach (3 s).
  poisson_bodies    True: step 6c reconstructs each connected body of the crop alone (links of 3 s, the
                    attachment reach; False: one reconstruction of the whole crop, version 12).
  poisson_bridges   True: step 6c fills across two bodies that are the ends of one limb the hole cuts through
                    (`limb_ends`: near points to one side of the centre, |u| >= 0.5, the ends pointing apart;
                    `tube_fill`); both bounds are geometry (a tube of radius up to 0.87 r; bent up to 90
                    degrees), the tube's tests step 6's.
  poisson_in_boxes  True: step 6c is tried in a region that keeps captured points too (an occlusion box); False
                    skips it there, a speed switch (methods/NOTES.md, "poisson_in_boxes", at versions 41 and 42): 3-10x
                    faster on real captures with occlusion boxes (Longdress, one 858k-point frame: 88 -> 8 s CPU), the
                    same D1 on most rows, but at version 42 D-FAUST occlusion -0.36 dB D1, Longdress -0.28 dB D1 and
                    NSHD 0.212 -> 0.254.
  cap               True: step 6d (voxelized input); its band, 2 s, is the rim's first rows of samples (one row
                    leaves gaps where the sampling is uneven); its flatness bound max(1 s, r / 20) is step 6's
                    hold-out bound, or on a wide opening a wobble of 3 degrees seen from the loop's centre.
  harmonic_cap      True: step 6d's membrane is harmonic (never leaves its loop's heights) and built afresh in each
                    frame; False: the thin plate of versions 13-28, reused by step 5. Its grid is step 6's, its
                    wall angle step 6's; no constant of its own.
  walled_cap_first  True: step 6d before 6c where its loop is walled and the region shallow past it (`cap_walled`); its
                    bound is step 6's height-field bound (a quarter of the points steep), its angle step 6's, its
                    depth the loop's radius (a round end's); False: 6c first (versions 13-29).
  membrane          True: step 6e; its ring (3 grid steps), graph and seeds are lozes-pde's defaults, its
                    hold-out band half that ring (round the open part), its bound and height-field test
                    step 6's (the latter with a majority bound, 0.5), its agreement rule step 4's.
  membrane_after_poisson  True: step 6e also runs after step 6c filled part of a region that keeps captured points
                    (version 42); its tests are step 6e's: no constant of its own.
  partial_sources   True: step 5b; its tests are step 2's and step 4's, its treatment step 7's.
  sheet             True: step 6f; its angle is step 6's steepness angle, its links step 4's reach (3 s).
  front             False: step 6b (see there for the measurement that keeps it off); its cell, round
                    count and residual bound follow from s, mls_neighbours and the rim's own fits.
  revoxelize        True: step 4b (voxelized data only); its bound t is read from each hole's rim.
  pool_adjacent     True: step 4b's fit also takes the copies of f-1 and f+1 (see there); no constant of its own.
  adjacent_first    True: frames beyond f+-1 only where f-1 and f+1 are not both sources (step 2, version 28).
  count_copies      True: step 4b keeps as many voxels as the fused copies hold (version 31; False: the rim's bound t).
  drop_layers       True: step 7b; its reach, 2 s, is step 2a's pairing reach (its 16 nearest, at least 3), its off-plane bound
                    `FLOAT_LAYER_SPACINGS` (on voxelized input the plane-cube test over `VOXEL_LAYER_REACH`,
                    `VOXEL_LAYER_NEIGHBOURS`), its surround bound (0.5) the mean of unit
                    directions that lie all to one side (near 1) or all round (near 0).
  coarse_retry      True: step 2a'; its first pair reach is the crop's own (r + 2 shell: a patch that moved
                    farther has left the crop), halved each round down to the shell (a.'s reach): no constant of its own.
  reuse_next        True: step 9, the holes left open take frame f+1's fill moved back (version 38); its tests are
                    step 5's and step 2b's, its treatment step 7's: no constant of its own.
  snap              "auto": voxelize when the input is voxelized (True/False force it).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from dpcbench.holes.regions import HoleRegion
from dpcbench.methods._front_fill import front_fill, local_quadric, rim_residual_bound
from dpcbench.methods._point_to_plane import point_to_plane_icp
from dpcbench.methods._registration import alignment_residual
from dpcbench.methods._spatial_fill import (
    _voxel_keys,
    cap_fill,
    cap_walled,
    even_subset,
    far_from,
    grown_agreeing,
    membrane_fill,
    over_captured_surface,
    plane_offsets,
    poisson_surface_fill,
    rim_sheet,
    rim_surface_fill,
    unique_voxels,
)
from dpcbench.methods.base import InpaintingMethod, Regions
from dpcbench.methods.lozes_pde import sampling_step
from dpcbench.methods.reference import icp_align
from dpcbench.metrics.neighbours import estimate_normals, point_spacing

#: most source points an ICP call pairs: a rigid motion has 6 unknowns, and 2000 evenly spread
#: pairs pin it down as well as the 10-20k of a large hole's shell on an 800k-point frame (the
#: alignment cost is then independent of the point density)
ICP_POINTS = 2000

#: most rim voxels step 4b's bound is read from (with their free neighbours): a statistic of the rim,
#: so an evenly strided subset gives it at a fixed cost per hole
CALIBRATION_POINTS = 1000

#: points of an MLS quadric fit (``mls_neighbours="auto"``): 20, the quadric's 6 coefficients over-determined
#: about 3 times (a disc of ~2.5 s); for the voxel decisions of steps 1b and 4b (and 6b) on voxelized input 28,
#: the points of a disc of step 4's reach, 3 s (pi 3^2): captured voxel centres carry the capture's rounding, up
#: to half a voxel on each axis, which a fit averages out over more points (methods/NOTES.md "version 25")
FIT_NEIGHBOURS = 20
VOXEL_FIT_NEIGHBOURS = 28

#: how far step 4b's candidate voxels (`surface_voxels`) may lie from the nearest copied point: one voxel edge.
#: The copies are another frame's voxels moved by a motion, one a cube that surface crossed there, so a cube
#: the copied surface crosses holds a copied point or is next to one; a cube farther off is one only the
#: quadric says the surface crosses, and where a misaligned copy sits in the fit's support (step 4b pools
#: f-1's and f+1's) the quadric is off there. Version 37; sqrt 3 before (the 26-neighbourhood): samba
#: independent (seeds 0-2) put 18 voxels 1.41-1.73 from the truth in 5 of 30 frames, every one of them
#: 1.03-1.71 from the nearest copied point, while 98-100 % of the voxels on the truth lie within 1 of one
#: (methods/NOTES.md). Only step 4b's copies: the reused fill and step 5b's copies are projected onto a fit
#: first (step 7), no longer one a captured voxel, and one edge there lost human occlusion 14 dB (version 36)
COPY_REACH = 1.0

#: step 7b's bound on how far off the captured surface's plane a fill point must lie to be a second layer over it, on
#: float samples, in spacings: half a spacing (two samplings of one surface lie about that far apart, step 2b's
#: reasoning); the plane is that of its 16 nearest captured points within 2 s
FLOAT_LAYER_SPACINGS = 0.5
#: step 7b on voxelized input: a voxel is a layer when the captured surface's plane does not cross its unit cube (the
#: voxelization rule of steps 1b and 4b), the plane fitted to the ``VOXEL_LAYER_NEIGHBOURS`` captured voxels within
#: ``VOXEL_LAYER_REACH`` voxels: the voxels of a disc of radius 4 (pi 4^2 ~ 50). A staircase's voxels scatter up to half
#: a cube diagonal about its plane, and a smaller disc tilts its fitted plane by that scatter: on voxelized planes
#: (five tilts, one-off; the test takes the same) 2 s and 16 voxels read 4-28 of a gap's own 32-75 voxels as off the
#: plane, 4 voxels and 50 at most 4, while 97-100 % of a layer one voxel above is read as one. A layer one voxel off a captured surface is what
#: a copy misaligned by a voxel lays (samba occlusion: 132-221 such voxels a frame in its widest box,
#: methods/NOTES.md "version 40"); version 39 took 1 voxel off a 2-voxel fit's plane, which let them all pass
VOXEL_LAYER_REACH = 4.0
VOXEL_LAYER_NEIGHBOURS = 50


# -- steps, as functions on arrays (each tested on its own) -------------------------------------------

def seen_rim_residual(source_tree: cKDTree, rim: np.ndarray, rotation: np.ndarray, translation: np.ndarray,
                      source_holes: list[HoleRegion]) -> float:
    """`alignment_residual` of ``rim`` (K, 3) to the source moved by (R, t), over the rim points whose
    place in the source's frame, (q - t) R, lies in none of ``source_holes`` (the source frame's own hole
    regions, in its coordinates): a rim point where the source has a hole has no counterpart there, and
    its distance measures the hole, not the alignment. inf when fewer than 6 rim points are left."""
    back = (np.asarray(rim) - translation) @ rotation
    seen = np.ones(len(back), dtype=bool)
    for hole in source_holes:
        seen &= ~hole.contains(back)
    if seen.sum() < 6:
        return float("inf")
    return alignment_residual(source_tree, rim[seen], rotation, translation)


def rim_displacement(rim: np.ndarray, moved_source: np.ndarray, max_distance: float) -> tuple[np.ndarray, np.ndarray]:
    """Normal residual of the rim after a rigid alignment: (rim points kept (K, 3), v (K, 3)).

    Each rim point q pairs with its nearest ``moved_source`` point p; pairs longer than
    ``max_distance`` (the source has a hole there) are dropped. v_q = ((q - p) . n_p) n_p, n_p the
    PCA normal of p's 10 nearest source points: the part of the misfit that bends the surface (the
    tangential part is only the two samplings' offset)."""
    if len(rim) == 0 or len(moved_source) < 3:
        return np.zeros((0, 3)), np.zeros((0, 3))
    tree = cKDTree(moved_source)
    dist, idx = tree.query(rim)
    keep = dist <= max_distance
    if not keep.any():
        return np.zeros((0, 3)), np.zeros((0, 3))
    p = moved_source[idx[keep]]
    n = estimate_normals(moved_source, 10, queries=p, tree=tree)
    offset = np.einsum("ij,ij->i", rim[keep] - p, n)
    return rim[keep], offset[:, None] * n


def interpolate_displacement(points: np.ndarray, anchors: np.ndarray, displacement: np.ndarray,
                             neighbours: int = 32) -> np.ndarray:
    """Shepard interpolation (P, 3) of the ``displacement`` (K, 3) given at ``anchors`` (K, 3) to
    ``points`` (P, 3): sum_i w_i v_i / sum_i w_i over the ``neighbours`` nearest anchors,
    w_i = 1 / max(d_i, 1e-12)^2. Zero when there is no anchor."""
    if len(anchors) == 0 or len(points) == 0:
        return np.zeros((len(points), 3))
    k = int(min(neighbours, len(anchors)))
    dist, idx = cKDTree(anchors).query(points, k=k)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    weight = 1.0 / np.maximum(dist, 1e-12) ** 2
    return np.einsum("pk,pki->pi", weight, displacement[idx]) / weight.sum(axis=1, keepdims=True)


def mls_project(points: np.ndarray, support: np.ndarray, neighbours: int = 20,
                support_tree: cKDTree | None = None) -> np.ndarray:
    """``points`` (P, 3) moved onto the moving-least-squares quadric of their ``neighbours`` nearest
    ``support`` points (step 7 of the module docstring). Points with fewer than 6 support points
    near are returned unchanged."""
    return mls_fit(points, support, neighbours, support_tree)[0]


def mls_fit(points: np.ndarray, support: np.ndarray, neighbours: int = 20,
            support_tree: cKDTree | None = None) -> tuple[np.ndarray, np.ndarray]:
    """`mls_project` with the fit's unit normals: (projected (P, 3), normal (P, 3), the PCA normal of
    each point's support neighbourhood; zero where the point is returned unchanged)."""
    foot, normal, _ = local_quadric(points, support, neighbours, support_tree)
    return foot, normal


def crossed_voxels(region: HoleRegion, support: np.ndarray, occupied: cKDTree, *, neighbours: int = 20,
                   front: float = float(np.sqrt(3.0)), max_rounds: int = 64, with_closed: bool = False):
    """Voxel fill of ``region`` on integer (voxelized) data by the data's own voxelization rule,
    grown from the rim inwards (step 1b of the module docstring). Returns integer (P, 3) voxels, or
    (voxels, closed) with ``with_closed``: closed is True when the growth stopped by itself (a round
    accepted nothing, or no candidate was left within reach) before ``max_rounds``.

    Candidates: the integer points inside ``region`` that ``occupied`` (frame f's points and the
    new points so far) does not hold. Each round judges the candidates within ``front`` (sqrt 3:
    the 26 neighbours of a voxel) of the support (``support`` (K, 3), the rim, grown by every voxel
    accepted so far): the `mls_fit` quadric of a candidate c's ``neighbours`` nearest support points
    gives its foot point p and unit normal n, and c is accepted when that surface crosses c's
    unit cube, |(c - p) . n| <= (|n_x| + |n_y| + |n_z|) / 2 (the exact test for a plane and a cube;
    the rule by which voxelized captures and our stand-ins are made: one voxel per cube the surface
    passes through). Every candidate is judged once, in the round its first support point comes
    within reach, so the fill grows across the hole one voxel shell a round and stops where no
    judged voxel is crossed (the surface left the hole, or the fit no longer reaches it)."""
    support = np.asarray(support, dtype=np.float64)
    # candidates are generated round by round round the support points added last (at first, those within
    # reach of R), not listed over R's bounding cube: the cube is O(r^3) integer points (63 million for a
    # 199-voxel occlusion opening, 17 s a frame), the grown shells O(r^2). Same candidates, same rounds.
    judged_keys = np.zeros(0, dtype=np.int64)
    origin = np.floor(region.center - region.bounding_radius) - 3
    side = np.int64(np.ceil(2 * region.bounding_radius) + 7)
    fresh = support[region.contains(support, margin=front * (1 + 1e-9))]
    accepted: list[np.ndarray] = []
    closed = False
    for _ in range(int(max_rounds)):
        judged = _reachable_voxels(fresh, region, front)
        if len(judged):
            judged = judged[~np.isin(_voxel_keys(judged, origin, side), judged_keys, assume_unique=True)]
            judged = judged[far_from(judged, occupied, 0.5)] if len(judged) else judged
        if not len(judged) or len(support) < 6:
            closed = True
            break
        judged_keys = np.union1d(judged_keys, _voxel_keys(judged, origin, side))
        tree = cKDTree(support)
        foot, normal = mls_fit(judged, support, neighbours, tree)
        off = np.abs(np.einsum("ij,ij->i", judged - foot, normal))
        crossed = (off <= np.abs(normal).sum(axis=1) / 2.0) & (np.abs(normal).sum(axis=1) > 0)
        if not crossed.any():
            closed = True
            break
        fresh = judged[crossed]
        accepted.append(fresh)
        support = np.vstack([support, fresh])
    voxels = np.vstack(accepted) if accepted else np.zeros((0, 3))
    return (voxels, closed) if with_closed else voxels


def _reachable_voxels(points: np.ndarray, region: HoleRegion, reach: float) -> np.ndarray:
    """The integer points inside ``region`` within ``reach`` (at most sqrt 3) of a point of ``points``
    (P, 3), unique rows in lexicographic order: the integer points of the 5^3 block round each point's
    nearest voxel, kept by distance."""
    if not len(points):
        return np.zeros((0, 3))
    offsets = np.stack(np.meshgrid(*[np.arange(-2, 3)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    centres = unique_voxels(np.floor(points + 0.5))
    integer = bool(np.all(np.floor(points + 0.5) == points))
    if integer:  # a voxel's integer points within sqrt 3 are its 26 neighbours
        offsets = offsets[np.abs(offsets).max(axis=1) <= 1]
    cand = unique_voxels((centres[:, None, :] + offsets[None, :, :]).reshape(-1, 3))
    cand = cand[region.contains(cand)]
    if not integer and len(cand):
        cand = cand[~far_from(cand, cKDTree(points), reach * (1 + 1e-9))]
    return cand


def _free_neighbours(points: np.ndarray, occupied: cKDTree) -> np.ndarray:
    """The integer points within the 26-neighbourhood of the voxels of ``points`` (rounded) that
    ``occupied`` does not hold (none within 0.5), unique rows."""
    offsets = np.stack(np.meshgrid(*[np.arange(-1, 2)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    cand = unique_voxels((np.floor(points + 0.5)[:, None, :] + offsets[None, :, :]).reshape(-1, 3))
    return cand[far_from(cand, occupied, 0.5)] if len(cand) else cand


def crossing_offset(voxels: np.ndarray, support: np.ndarray, neighbours: int, tree: cKDTree | None = None
                    ) -> np.ndarray:
    """|(c - p) . n| / ((|n_x| + |n_y| + |n_z|) / 2) for each voxel c (V,), with p, n the `mls_fit` quadric's
    foot point and normal from its ``neighbours`` nearest ``support`` points: <= 1 exactly when that
    surface's tangent plane crosses c's unit cube (inf where there is no fit)."""
    foot, normal, _ = local_quadric(voxels, support, neighbours, tree)
    l1 = np.abs(normal).sum(axis=1)
    off = np.abs(np.einsum("ij,ij->i", voxels - foot, normal))
    return np.where(l1 > 0, 2.0 * off / np.where(l1 > 0, l1, 1.0), np.inf)


def rim_crossing_threshold(rim: np.ndarray, region: HoleRegion, local: np.ndarray, occupied: cKDTree,
                           neighbours: int) -> float:
    """The `crossing_offset` bound that best reproduces the capture's own voxelization on the rim of
    ``region``: ``rim`` (K, 3) frame f's voxels around the region, ``local`` (L, 3) frame f's points near
    it and ``occupied`` their k-d tree. Over the rim voxels (occupied) and the free voxels next to them
    outside the region, each judged by the quadric of its ``neighbours`` nearest ``local`` points, the
    bound t minimising (occupied with offset > t) + (free with offset <= t), midway to the next offset
    seen. Captures differ in how thickly they voxelize a surface (every cube it crosses, t = 1; the cubes
    their samples fall in, fewer where a cube is only clipped), so the rule is read from the frame
    itself, per hole. 1.0 without enough data."""
    free = _free_neighbours(rim, occupied) if len(rim) else np.zeros((0, 3))
    free = free[~region.contains(free)] if len(free) else free
    if len(rim) < 6 or not len(free) or len(local) < 6:
        return 1.0
    tree = cKDTree(local)
    occupied_off = np.sort(crossing_offset(rim, local, neighbours, tree))
    free_off = np.sort(crossing_offset(free, local, neighbours, tree))
    bounds = np.concatenate([occupied_off, free_off])
    bounds = np.unique(bounds[np.isfinite(bounds) & (bounds <= 2.0)])
    if not len(bounds):
        return 1.0
    errors = (len(occupied_off) - np.searchsorted(occupied_off, bounds, side="right")) + \
        np.searchsorted(free_off, bounds, side="right")
    best = int(np.argmin(errors))
    # midway to the next offset seen: the widest margin on both sides (the hole's voxels are judged by
    # other fits than the rim's, so a bound at the last occupied offset loses those just above it)
    return float((bounds[best] + bounds[best + 1]) / 2.0) if best + 1 < len(bounds) else float(bounds[best])


def surface_voxels(points: np.ndarray, region: HoleRegion, support: np.ndarray, occupied: cKDTree,
                   neighbours: int = 20, threshold: float = 1.0, count: int | None = None,
                   reach: float = float(np.sqrt(3.0))) -> np.ndarray:
    """The voxels of ``region`` that the surface through ``points`` (P, 3; sub-voxel positions, e.g. an
    aligned copy) passes through: candidates are the free integer points (farther than 0.5 from
    ``occupied``) inside ``region`` within ``reach`` of a point (sqrt 3: the 26-neighbourhood of its voxel;
    step 4b passes `COPY_REACH`, one voxel edge), kept when their `crossing_offset` from the
    quadric of ``support`` is at most ``threshold`` (1: every cube the surface crosses); or, given ``count``,
    the ``count`` of them with the smallest offsets (ties kept). Returns integer (V, 3) voxels, sorted. Why:
    rounding each moved sample to its nearest voxel puts 7-19 % of them one voxel off the voxels the surface
    crosses (methods/NOTES.md); re-voxelizing the copied surface follows the capture's rule."""
    points = np.asarray(points, dtype=np.float64)
    cand = _free_neighbours(points, occupied)
    cand = cand[region.contains(cand)] if len(cand) else cand
    if len(cand):
        cand = cand[~far_from(cand, cKDTree(points), reach * (1 + 1e-9))]
    if not len(cand):
        return np.zeros((0, 3))
    offsets = crossing_offset(cand, support, neighbours)
    if count is not None:
        if count <= 0:
            return np.zeros((0, 3))
        nth = min(count, len(offsets)) - 1
        threshold = float(np.partition(offsets, nth)[nth])
    return cand[offsets <= threshold]


def snap_to_voxels(points: np.ndarray, occupied: np.ndarray) -> np.ndarray:
    """``points`` rounded (half up) to the integer grid, one per voxel, minus the voxels in
    ``occupied`` (integer (N, 3)); sorted rows."""
    if len(points) == 0:
        return np.zeros((0, 3))
    voxels = unique_voxels(np.floor(np.asarray(points) + 0.5))
    if len(occupied):
        dist, _ = cKDTree(occupied).query(voxels, distance_upper_bound=0.5)
        voxels = voxels[~np.isfinite(dist)]
    return voxels


def rows_in(points: np.ndarray, table: np.ndarray) -> np.ndarray:
    """(P,) bool: which rows of ``points`` (P, 3) occur exactly in ``table`` (T, 3)."""
    if len(points) == 0 or len(table) == 0:
        return np.zeros(len(points), dtype=bool)
    both = np.ascontiguousarray(np.vstack([points, table]), dtype=np.float64)
    _, code = np.unique(both, axis=0, return_inverse=True)
    code = code.ravel()
    return np.isin(code[:len(points)], code[len(points):])


def disagreeing(points: np.ndarray, accepted: np.ndarray, reach: float, tolerance: float) -> np.ndarray:
    """Mask (P,) of ``points`` that lie farther than ``tolerance`` off the PCA plane of their (up to)
    8 nearest ``accepted`` points within ``reach`` (points with fewer than 3 such are not judged)."""
    judged, off = plane_offsets(points, accepted, reach)
    return judged & (off > tolerance)




@dataclass(frozen=True)
class PlaneTarget:
    """A point-to-plane ICP target: points (T, 3), their unit normals (T, 3) (PCA of each point's 16
    nearest target points, arbitrary sign) and a cKDTree on the points."""

    points: np.ndarray
    normals: np.ndarray
    tree: cKDTree


def plane_target(target: np.ndarray) -> PlaneTarget:
    """The `PlaneTarget` of ``target`` (T, 3) that `refine_point_to_plane` pairs against: built once and
    reused for every source aligned to the same target. Normals by open3d's KNN estimate (each point's
    normal computed on its own, so it is repeatable; its neighbour choice among equidistant voxels is
    the one version 4 was measured with: with `estimate_normals`' cKDTree neighbours instead, human 290k, 3
    medium holes, W = 3 measured D1 / D2 29.94 / 33.30 dB against 30.68 / 33.89 dB)."""
    import open3d as o3d

    points = np.asarray(target, dtype=np.float64)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(16))
    return PlaneTarget(points, np.asarray(cloud.normals).copy(), cKDTree(points))


def refine_point_to_plane(source: np.ndarray, target: np.ndarray, max_distance: float,
                          init: tuple[np.ndarray, np.ndarray], iterations: int = 30,
                          target_cloud: PlaneTarget | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Rigid (R, t) refining ``init`` by point-to-plane ICP (`_point_to_plane.point_to_plane_icp`):
    minimises sum_i ((R s_i + t - q_i) . n_i)^2 over the pairs (source s_i, nearest target q_i) closer
    than ``max_distance``, n_i the PCA normal of q_i's 16 nearest target points. Returns ``init`` when
    fewer than 6 pairs are in reach. ``target_cloud``: `plane_target` of ``target`` (reused).
    Deterministic: repeated calls give bitwise equal transforms."""
    rotation, translation = init
    if len(source) < 6 or len(target) < 16 or iterations <= 0:
        return rotation, translation
    if target_cloud is None:
        target_cloud = plane_target(target)
    return point_to_plane_icp(source, target_cloud.points, target_cloud.normals, max_distance, (rotation, translation),
                              iterations=int(iterations), target_tree=target_cloud.tree)


# -- the method ------------------------------------------------------------------------------------

class TemporalFusion(InpaintingMethod):
    """Motion-compensated fusion of every frame within +-``window`` that saw the missing surface,
    surface projection, voxel snapping, reuse of the previous frame's fill (replacing, never adding) and,
    where a hole stayed open, of the next frame's,
    thin-plate-spline fill of the rim's surface where no frame saw it and the surface is trusted.
    See the module docstring for each step and for how each default was chosen."""

    name = "temporal-fusion"
    summary = ("fills thin voxel gaps from the frame's own rim by the voxelization rule; elsewhere "
               "fuses the hole's patch from every frame within +-W (rigid + rim-driven non-rigid motion "
               "compensation), MLS surface projection, steady reuse of the previous fill (of the next one where a "
               "hole stayed open), spline fill of the "
               "rim's surface (or of the hole's own sheet of it) where no frame saw it and the fit is trusted; "
               "a graph membrane across the open parts of occlusion boxes")
    version = "42"  # 7: trimmed residual summed in sorted order (independent of the CPU); 8: revoxelize;
    # 9: revoxelize the reused fill too; 12: step 6c, screened Poisson fill of the holes step 6 refuses (developed
    # as 8-11 on a branch beside 8-9, merged with them); 13: step 6c reconstructs each connected body of the crop
    # alone, and step 6d (cap) spans flat openings on voxelized input (developed side by side, merged);
    # 14: step 6c orients normals by its own spanning tree over the 16-NN graph (an edge leaving the tangent
    # planes costs more), sign per component; 15: step 6e, the membrane fill of what steps 6-6d refused, not reused;
    # 16: step 5b, copies from frames with their own hole near R, not reused; 17: step 6f, step 6 retried on the
    # hole's own sheet of the crop; 18: step 5b's agreement tolerance widened by the copy's rim residual;
    # 19: step 6e spans an open disc too where the anchors' quadric bounds the membrane's sag; 20: step 6e's
    # hold-out leaves out the band round the open part (not the box), plus its height-field and two-layer tests;
    # 21: step 6c's hold-out miss is judged less the ring's own scatter about the whole body's surface;
    # 22: step 6c spans a hole that cuts a limb through by a spline in the tube's chart (`tube_fill`);
    # 23: f-1's motion carries its fill when it passes step 2b on the rim f-1 saw (`seen_rim_residual`);
    # 24: step 6e spans a box a second surface crosses on the hole's sheet (`_flat_anchors`, `_sheet_bounded`);
    # 25: steps 1b and 4b's voxel decisions on voxelized input fit 28 points (a disc of 3 s), not 20;
    # 26: step 4b's fit pools the copies of f-1 and f+1 (`pool_adjacent`), 28 points a copy;
    # 27: `local_quadric` sums by rows (faster; the same fits to 1e-13, so a decision at a threshold may flip);
    # 28: frames beyond f+-1 are aligned only where f-1 and f+1 are not both sources (`adjacent_first`);
    # 29: step 6d's cap is the harmonic membrane of its loop, not the thin plate, and not reused (`harmonic_cap`);
    # 30: step 6d before 6c where walls rise from the opening (`walled_cap_first`);
    # 31: step 4b keeps as many voxels as the copies hold (`count_copies`); 32 (measured, not kept): step 5b's
    # copies anchor step 6e's membrane; 33: the same where its anchors pass the height-field test without them;
    # 34: step 6e's sag bound judged over the widest open disc among its anchors, not the region (`_open_radius`);
    # 35: step 6d before 6c only where the region is shallow past the walled loop's plane (`cap_walled`);
    # 36 (measured, not kept): `surface_voxels` takes a voxel only within one voxel edge of a copied point, not
    # sqrt 3; 37: the same for step 4b's copies only (`COPY_REACH`); 38: step 9, a hole left open in frame f takes
    # what frame f+1 found there, moved back (``reuse_next``); 39: step 7b, no second layer over the captured
    # surface (``drop_layers``); 40: on voxelized input step 7b judges a voxel by whether the captured plane
    # (50 voxels within 4) crosses its cube; 41: step 2a', an alignment that misses the bound is tried again coarse to
    # fine, the crop following the patch (``coarse_retry``); 42: step 6e also on what step 6c left open in a region
    # that keeps captured points (``membrane_after_poisson``)
    uses_neighbour_frames = True
    needs_regions = False
    detects_holes = True

    def __init__(self, window: int = 3, shell_factor: float = 0.5, shell_spacings: float = 4.0,
                 icp_iterations: int = 30, accept_spacings: float = 1.0, refine: bool = True, deform: bool = True,
                 deform_neighbours: int = 32, gap_spacings: float = 0.5, fill_gap_spacings: float = 1.0,
                 reuse_previous: bool = True, fallback: bool = True, surface_holdout_spacings: float = 1.0,
                 mls_neighbours: int | str = "auto", rim_fill: bool = True, poisson: bool = True,
                 poisson_bodies: bool = True, poisson_bridges: bool = True, cap: bool = True, harmonic_cap: bool = True,
                 walled_cap_first: bool = True, membrane: bool = True, front: bool = False,
                 partial_sources: bool = True, sheet: bool = True, revoxelize: bool = True, pool_adjacent: bool = True,
                 adjacent_first: bool = True, count_copies: bool = True, reuse_next: bool = True,
                 drop_layers: bool = True, coarse_retry: bool = True,
                 poisson_in_boxes: bool = True, membrane_after_poisson: bool = True, snap: bool | str = "auto") -> None:
        self.window = window
        self.shell_factor = shell_factor
        self.shell_spacings = shell_spacings
        self.icp_iterations = icp_iterations
        self.accept_spacings = accept_spacings
        self.refine = refine
        self.deform = deform
        self.deform_neighbours = deform_neighbours
        self.gap_spacings = gap_spacings
        self.fill_gap_spacings = fill_gap_spacings
        self.reuse_previous = reuse_previous
        self.fallback = fallback
        self.surface_holdout_spacings = surface_holdout_spacings
        self.mls_neighbours = mls_neighbours
        self.rim_fill = rim_fill
        self.poisson = poisson
        self.poisson_bodies = poisson_bodies
        self.poisson_bridges = poisson_bridges
        self.cap = cap
        self.harmonic_cap = harmonic_cap
        self.walled_cap_first = walled_cap_first
        self.membrane = membrane
        self.partial_sources = partial_sources
        self.sheet = sheet
        self.front = front
        self.revoxelize = revoxelize
        self.pool_adjacent = pool_adjacent
        self.adjacent_first = adjacent_first
        self.count_copies = count_copies
        self.reuse_next = reuse_next
        self.drop_layers = drop_layers
        self.coarse_retry = coarse_retry
        self.poisson_in_boxes = poisson_in_boxes
        self.membrane_after_poisson = membrane_after_poisson
        self.snap = snap

    # -- parameters ---------------------------------------------------------------------------
    def _validate(self) -> None:
        def integer(name, least):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < least:
                raise ValueError(f"{self.name}: {name} must be an integer >= {least}, got {value!r}")

        def number(name, positive):
            value = getattr(self, name)
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and (value > 0 if positive else value >= 0)
            if not ok:
                raise ValueError(f"{self.name}: {name} must be a number {'> 0' if positive else '>= 0'}, got {value!r}")

        integer("window", 0)
        integer("icp_iterations", 0)
        integer("deform_neighbours", 1)
        if self.mls_neighbours != "auto" and (not isinstance(self.mls_neighbours, (int, np.integer))
                                              or isinstance(self.mls_neighbours, bool) or self.mls_neighbours < 0):
            raise ValueError(f"{self.name}: mls_neighbours must be 'auto' or an integer >= 0, got {self.mls_neighbours!r}")
        number("shell_factor", False)
        number("shell_spacings", True)
        number("accept_spacings", True)
        number("gap_spacings", False)
        number("fill_gap_spacings", False)
        number("surface_holdout_spacings", True)
        for name in ("refine", "deform", "reuse_previous", "fallback", "rim_fill", "poisson", "poisson_bodies",
                     "poisson_bridges", "cap", "harmonic_cap", "walled_cap_first", "membrane", "front", "partial_sources",
                     "sheet", "revoxelize", "pool_adjacent", "adjacent_first", "count_copies", "reuse_next",
                     "drop_layers", "coarse_retry", "poisson_in_boxes",
                     "membrane_after_poisson"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{self.name}: {name} must be true or false, got {getattr(self, name)!r}")
        if self.snap not in ("auto", True, False):
            raise ValueError(f"{self.name}: snap must be 'auto', true or false, got {self.snap!r}")

    # -- sequence ------------------------------------------------------------------------------
    def inpaint(self, frames: list[np.ndarray], regions: Regions = None) -> list[np.ndarray]:
        self._validate()
        frames, regions = self._check_inputs(frames, regions)
        if regions is None:
            from dpcbench.methods.reference import detect_regions

            regions = detect_regions(frames, self.name)
        if len(frames) == 1 and any(regions[0]):
            warnings.warn(f"{self.name}: a one-frame sequence has no other frame to copy from; "
                          "using the spatial fill only", RuntimeWarning, stacklevel=2)
        trees: dict[int, cKDTree] = {}

        def tree_of(g):
            if g not in trees:
                # built for crops and distances only: the unbalanced, non-compact build is ~40% faster
                # on an 800k-point frame, and the crops are sorted, so nothing depends on its layout
                trees[g] = cKDTree(frames[g], balanced_tree=False, compact_nodes=False)
            return trees[g]

        integer = all(np.array_equal(frame, np.round(frame)) for frame in frames)
        voxelized = self.snap is True or (self.snap == "auto" and integer)
        largest = max(range(len(frames)), key=lambda g: len(frames[g]))
        spacing = 1.0 if integer else point_spacing(frames[largest], tree=tree_of(largest))
        # the spatial fill's grid step on unvoxelized data: 1 / sqrt(areal density), so a square grid has the
        # frame's density (the median nearest-neighbour distance of an uneven sampling is about half that,
        # and a grid of that step put ~4 points where one was missing on D-FAUST)
        step = spacing if integer else sampling_step(frames[largest])
        context = dict(step=step, frames=frames, regions=regions, tree_of=tree_of, spacing=spacing, voxelized=voxelized,
                       neighbours=self._fit_neighbours(voxelized), projection_neighbours=self._fit_neighbours(False))
        context["back_motions"] = {}
        outputs: list[np.ndarray] = []
        found_of: dict[int, np.ndarray] = {}  # the points each frame found itself (`_fill_frame`), for step 9
        previous_fill = np.zeros((0, 3))
        for f, frame in enumerate(frames):
            for old in [g for g in trees if g < f - int(self.window)]:
                del trees[old]
            if not regions[f]:
                outputs.append(frame.copy())
                previous_fill = np.zeros((0, 3))
                continue
            added, previous_fill, found_of[f] = self._fill_frame(f, regions[f], previous_fill, context)
            outputs.append(np.vstack([frame, added]) if len(added) else frame.copy())
        if self.reuse_next:
            # step 9, last frame first, so a fill found late in a persistent hole reaches back over every frame
            for f in range(len(frames) - 2, -1, -1):
                for old in [g for g in trees if g > f + 1]:
                    del trees[old]
                later = found_of.get(f + 1)
                if f not in found_of or later is None or not len(later):
                    continue
                back = self._back_fill(f, later, outputs[f][len(frames[f]):], context)
                if len(back):
                    outputs[f] = np.vstack([outputs[f], back])
                    found_of[f] = np.vstack([found_of[f], back])
        return outputs

    # -- one frame -----------------------------------------------------------------------------
    def _fill_frame(self, f, frame_regions, previous_fill, ctx) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(the points added to frame f; those of them that frame f + 1 may reuse: all but steps 5b, 6d and 6e's;
        those of the latter that frame f found itself, not reused from f - 1: what step 9 carries back to f - 1)."""
        frames, spacing = ctx["frames"], ctx["spacing"]
        frame, tree = frames[f], ctx["tree_of"](f)
        new_parts: list[np.ndarray] = []
        ctx["not_reused"], ctx["from_previous"] = [], []
        ctx["back_motions"][f] = next_motions = []
        for k, region in enumerate(frame_regions):
            fill = self._fill_region(f, region, previous_fill, ctx)
            next_motions.append(ctx["next_motion"])
            if len(fill) and self.drop_layers and self._keeps_captured(tree, frame, region):
                # step 7b: in a region that keeps captured points (an occlusion box), nothing laid as a second
                # layer over them (a copy misaligned there); on voxelized data only beyond one voxel off their
                # plane, as a voxelized plane's own staircase scatters up to half a cube diagonal (0.87) about it
                fill = fill[~self._over_captured(fill, tree, spacing, ctx["voxelized"])]
            if len(fill):
                # overlapping regions: what an earlier region filled is not filled again
                for earlier in frame_regions[:k]:
                    fill = fill[~earlier.contains(fill)]
                new_parts.append(fill)
        if not new_parts:
            return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3))
        added = np.vstack(new_parts)
        if ctx["voxelized"]:
            added = snap_to_voxels(added, frame[self._near_regions(tree, frame_regions, spacing * 2)])
        else:
            added = added[far_from(added, tree, self.gap_spacings * spacing)]
        reusable = added
        if ctx["not_reused"]:
            # step 5b's copies and the membranes of steps 6d and 6e rest on frames round f as they are, so frame f + 1
            # builds its own rather than reusing these (step 5): reused, they drift and pile up in a persistent
            # occlusion box
            reusable = added[~rows_in(added, self._as_added(ctx["not_reused"], ctx))]
        found = reusable
        if ctx["from_previous"]:
            # frame f - 1 holds these already: carried back (step 9) after a round trip they would lie beside it
            found = reusable[~rows_in(reusable, self._as_added(ctx["from_previous"], ctx))]
        return added, reusable, found

    @staticmethod
    def _as_added(parts: list[np.ndarray], ctx) -> np.ndarray:
        """``parts`` stacked as `_fill_frame` puts them in ``added`` (rounded to voxels on voxelized data)."""
        points = np.vstack(parts)
        return np.floor(points + 0.5) if ctx["voxelized"] else points

    @staticmethod
    def _over_captured(fill, tree, spacing, voxelized) -> np.ndarray:
        """Step 7b's mask of ``fill`` (a second layer over frame f's captured points, ``tree``)."""
        if not voxelized:
            return over_captured_surface(fill, tree, spacing, off_plane_spacings=FLOAT_LAYER_SPACINGS)
        return over_captured_surface(fill, tree, spacing, reach_spacings=VOXEL_LAYER_REACH,
                                     neighbours=VOXEL_LAYER_NEIGHBOURS, off_plane_spacings=None)

    @staticmethod
    def _keeps_captured(tree, frame, region) -> bool:
        """Whether frame f (``frame``, its k-d tree ``tree``) has points inside ``region``."""
        near = tree.query_ball_point(region.center, region.bounding_radius)
        return bool(len(near)) and bool(region.contains(frame[np.asarray(near, dtype=np.int64)]).any())

    @staticmethod
    def _near_regions(tree, frame_regions, margin) -> np.ndarray:
        idx = [tree.query_ball_point(r.center, r.bounding_radius + margin) for r in frame_regions]
        return np.unique(np.concatenate([np.asarray(i, dtype=np.int64) for i in idx])) if idx else np.zeros(0, np.int64)

    def _shell(self, region, spacing) -> float:
        return max(self.shell_factor * region.bounding_radius, self.shell_spacings * spacing)

    def _crop(self, f, region, ctx) -> tuple[np.ndarray, np.ndarray, float]:
        """Step 1: (frame f's points within r + 2 shell of R, in the frame's order; those of them within the
        shell of R, the rim; the shell width)."""
        shell = self._shell(region, ctx["spacing"])
        reach = region.bounding_radius + 2 * shell
        idx = np.asarray(ctx["tree_of"](f).query_ball_point(region.center, reach, return_sorted=True), dtype=np.int64)
        local = ctx["frames"][f][idx]
        return local, local[region.contains(local, margin=shell)], shell

    def _back_fill(self, f, later_fill, added, ctx) -> np.ndarray:
        """Step 9: frame f+1's fill ``later_fill`` (M, 3) moved back to frame f by f+1's motion, where frame f's
        holes are still open after its own fill ``added`` (A, 3); step 5's tests and step 7's treatment.
        Returns (P, 3) points to add to frame f."""
        spacing, frame = ctx["spacing"], ctx["frames"][f]
        frame_regions = ctx["regions"][f]
        parts: list[np.ndarray] = []
        for k, (region, motion) in enumerate(zip(frame_regions, ctx["back_motions"][f])):
            if motion is None:
                continue
            rotation, translation, field = motion
            moved = later_fill @ rotation.T + translation
            moved = self._deformed(moved[region.contains(moved)], field)
            if not len(moved):
                continue
            local, rim, shell = self._crop(f, region, ctx)
            local_tree = cKDTree(local)
            moved = moved[far_from(moved, local_tree, self.gap_spacings * spacing)]
            near = np.vstack([added, *parts])
            near = near[region.contains(near, margin=shell)]
            if len(near):
                moved = moved[far_from(moved, cKDTree(near), self.fill_gap_spacings * spacing)]
            moved = moved[~disagreeing(moved, rim, 3 * spacing, self.accept_spacings * spacing)]
            if not len(moved):
                continue
            moved = self._settle(moved, near, region, local, rim, local_tree, ctx)
            moved = moved[region.contains(moved, margin=spacing)]
            for earlier in frame_regions[:k]:
                moved = moved[~earlier.contains(moved)]
            parts.append(moved)
        if not parts:
            return np.zeros((0, 3))
        back = np.vstack(parts)
        if ctx["voxelized"]:
            back = snap_to_voxels(back, frame[self._near_regions(ctx["tree_of"](f), frame_regions, spacing * 2)])
            return back[~rows_in(back, added)] if len(added) else back
        return back[far_from(back, ctx["tree_of"](f), self.gap_spacings * spacing)]

    def _align(self, g, region, init, schedule, follow, local, rim, shell, local_cache, ctx):
        """Step 2a: frame g's points round where R lies in g, moved onto frame f's points ``local`` near R.
        One point-to-point ICP round of g's shell per pair reach in ``schedule``, from the motion ``init``
        (frame g -> f); with ``follow`` the crop is taken again round where R lies in g under each round's
        motion (step 2a'). Returns (source (K, 3), its k-d tree, rotation, translation, rim residual), None
        when g has fewer than 6 points there."""
        spacing = ctx["spacing"]
        reach = region.bounding_radius + 2 * shell
        rotation, translation = init
        source = None
        for max_distance in schedule:
            if source is None or follow:
                centre_g = (region.center - translation) @ rotation
                idx = np.asarray(ctx["tree_of"](g).query_ball_point(centre_g, reach, return_sorted=True), dtype=np.int64)
                if len(idx) < 6:
                    return None
                source = ctx["frames"][g][idx]
            # the source's shell is re-selected where it lands after the current motion, so the
            # source's own patch inside R never pairs with frame f's rim
            moved = source @ rotation.T + translation
            in_shell = ~region.contains(moved) & region.contains(moved, margin=shell)
            rotation, translation = icp_align(even_subset(source[in_shell], ICP_POINTS), local,
                                              max_distance=max_distance, max_iterations=int(self.icp_iterations),
                                              init=(rotation, translation))
        source_tree = cKDTree(source)
        residual = alignment_residual(source_tree, rim, rotation, translation)
        if self.refine:
            # point-to-plane from the converged point-to-point motion, pairs within 2 s: it
            # slides the samplings onto each other where point-to-point stops at half a spacing
            moved = source @ rotation.T + translation
            in_shell = ~region.contains(moved) & region.contains(moved, margin=shell)
            if "plane" not in local_cache:
                local_cache["plane"] = plane_target(local)  # one normal estimate per hole, not one per frame
            refined = refine_point_to_plane(even_subset(source[in_shell], ICP_POINTS), local, 2 * spacing,
                                            (rotation, translation), int(self.icp_iterations),
                                            target_cloud=local_cache["plane"])
            refined_residual = alignment_residual(source_tree, rim, *refined)
            if refined_residual <= residual:
                (rotation, translation), residual = refined, refined_residual
        return source, source_tree, rotation, translation, residual

    def _fill_region(self, f, region, previous_fill, ctx) -> np.ndarray:
        frames, spacing = ctx["frames"], ctx["spacing"]
        ctx["next_motion"] = None  # frame f+1's motion to f, for step 9 (set below when f+1 is aligned)
        local, rim, shell = self._crop(f, region, ctx)
        reach = region.bounding_radius + 2 * shell
        if len(rim) < 6:
            return np.zeros((0, 3))  # nothing around the hole to align to or to continue
        if ctx["voxelized"] and self.rim_fill:
            # step 1b: a thin gap (the rim's own fit closes it) is filled from frame f's rim alone
            thin, closed = crossed_voxels(region, local, cKDTree(local), neighbours=max(ctx["neighbours"], 6),
                                          max_rounds=self._rim_fill_rounds(ctx["neighbours"]), with_closed=True)
            if closed:
                return thin
        local_tree = cKDTree(local)

        # step 2: motion-compensated candidates, nearest frames first (chained starts)
        order = sorted((g for g in range(len(frames)) if g != f and abs(g - f) <= int(self.window)),
                       key=lambda g: (abs(g - f), g))
        motions: dict[int, tuple] = {f: (np.eye(3), np.zeros(3), None)}
        local_cache: dict = {}  # `plane_target` of ``local`` (points, normals, tree), for step 2a's refinement
        candidates: list[tuple[float, int, int, np.ndarray]] = []  # (rim residual, |g - f|, g, points)
        partial = []
        carried: tuple | None = None  # f-1's motion when it carries its fill only (step 2b)
        starts: dict[int, tuple] = {}  # motions that only start the farther frames' alignment (step 2a')
        for g in order:
            if self.adjacent_first and abs(g - f) > 1 and sum(gap == 1 for _, gap, _, _ in candidates) == 2:
                break  # f-1 and f+1 both saw R: farther frames only moved more (step 2, version 28)
            nearer = g - 1 if g > f else g + 1
            rotation0, translation0 = motions[nearer][:2] if nearer in motions else starts.get(nearer, motions[f][:2])
            centre_g = (region.center - translation0) @ rotation0
            # coverage test: frame g has a hole of its own over R or R's rim, so it lacks part of the
            # patch and its rim alignment pairs a holed shell (coherent holes): its motion still
            # carries the previous fill (step 5), but it is no source of points
            own_hole = any(np.linalg.norm(other.center - centre_g) < region.bounding_radius + other.bounding_radius + shell
                           for other in ctx["regions"][g])
            if own_hole and not (self.reuse_previous and g == f - 1) and not self.partial_sources:
                continue
            aligned = self._align(g, region, (rotation0, translation0), [shell] * 3, False, local, rim, shell,
                                  local_cache, ctx)
            if aligned is None:
                continue
            beyond = g + (1 if g > f else -1)
            # an own-hole frame's retry only starts the frame beyond it: none within the window, no retry
            retry_useful = not own_hole or (abs(beyond - f) <= int(self.window) and 0 <= beyond < len(frames))
            if self.coarse_retry and retry_useful and aligned[-1] > self.accept_spacings * spacing:
                # step 2a': a patch that moved farther than the shell, coarse to fine, the crop following it
                schedule = [reach / 2 ** k for k in range(int(np.ceil(np.log2(reach / shell))))] + [shell] * 3
                retried = self._align(g, region, (rotation0, translation0), schedule, True, local, rim, shell,
                                      local_cache, ctx)
                # kept only where it found R farther from the start than the shell: within it, the first
                # alignment could reach the patch, and a lower residual there is one more local minimum
                moved_far = retried is not None and np.linalg.norm(
                    (region.center - retried[3]) @ retried[2] - centre_g) > shell
                if moved_far and retried[-1] < aligned[-1]:
                    if not own_hole:
                        aligned = retried
                    elif retried[-1] <= self.accept_spacings * spacing:
                        # g has its own hole near R: its coarse motion only starts the farther frames' alignment;
                        # g itself is judged on its first one (step 2a')
                        starts[g] = retried[2:4]
            source, source_tree, rotation, translation, residual = aligned
            carries_only = False
            if residual > self.accept_spacings * spacing:
                # f-1 (f+1) with its own hole there: judged again on the rim it saw, its motion carries its fill
                # to f (step 5; step 9) though it is no source (step 2b)
                carrier = (g == f - 1 and self.reuse_previous) or (g == f + 1 and self.reuse_next)
                if not (own_hole and carrier
                        and seen_rim_residual(source_tree, rim, rotation, translation, ctx["regions"][g])
                        <= self.accept_spacings * spacing):
                    continue
                carries_only = True
            moved = source @ rotation.T + translation
            inside = region.contains(moved)
            field = None
            if self.deform:
                field = rim_displacement(rim, moved[~inside], 2 * spacing)
            if g == f + 1:
                ctx["next_motion"] = (rotation, translation, field)
            if carries_only:
                if g == f - 1:
                    carried = (rotation, translation, field)
                continue
            motions[g] = (rotation, translation, field)
            if inside.any() and not own_hole:
                candidates.append((residual, abs(g - f), g, self._deformed(moved[inside], field)))
            elif inside.any() and self.partial_sources:
                # a frame with its own hole near R: what it saw of R, used in step 5b
                partial.append((residual, abs(g - f), g, self._deformed(moved[inside], field)))

        # steps 3-4: fusion, the best-agreeing frame first, later ones only where nothing is yet
        candidates.sort(key=lambda c: (round(c[0] / spacing, 2), c[1], c[2]))
        accepted = np.zeros((0, 3))
        for rank, (_, _, _, points) in enumerate(candidates):
            points = points[far_from(points, local_tree, self.gap_spacings * spacing)]
            if rank and len(accepted):
                # only the parts the better frames did not see (hole-sized gaps, not their sampling),
                # and only where the points continue the surface of the rim and of what is accepted
                points = points[far_from(points, cKDTree(accepted), shell)]
                points = points[grown_agreeing(points, np.vstack([rim, accepted]), 3 * spacing,
                                               self.accept_spacings * spacing)]
            if len(points):
                accepted = np.vstack([accepted, points])
        full_copy = len(accepted)

        if ctx["voxelized"] and self.revoxelize and len(accepted):
            k = max(ctx["neighbours"], 6)
            bound = 1.0 if self.count_copies else \
                rim_crossing_threshold(even_subset(rim, CALIBRATION_POINTS), region, local, local_tree, k)
            fit_support, copies = [local, accepted], 1
            if self.pool_adjacent:
                # f-1's and f+1's copies when they were sources and not the one fused first: each is another
                # capture of R's surface aligned on its own, so one fit over all of them (k points a copy, the
                # same disc) averages their alignment errors; farther frames moved more and are left out
                for _, gap, _, points in candidates[1:]:
                    points = points[far_from(points, local_tree, self.gap_spacings * spacing)] if gap == 1 else points[:0]
                    if len(points):
                        fit_support, copies = fit_support + [points], copies + 1
            # as many voxels as the copies hold: they are the same capture's voxelization of the same surface
            # (the rim's bound is read where frame f's own fit judges its own voxels; a fit through aligned
            # copies judges the hole's with a wider scatter, so the same bound keeps too few or too many)
            accepted = surface_voxels(accepted, region, np.vstack(fit_support), local_tree, k * copies, bound,
                                      count=len(accepted) if self.count_copies else None, reach=COPY_REACH)
        copied = len(accepted)  # points copied from captured data; the rest is reused or spatial fill

        # step 5: the previous frame's fill, moved with the body, where the hole is still open
        carrying = motions.get(f - 1, carried)
        if self.reuse_previous and len(previous_fill) and carrying is not None:
            rotation, translation, field = carrying
            moved = previous_fill @ rotation.T + translation
            moved = self._deformed(moved[region.contains(moved)], field)
            moved = moved[far_from(moved, local_tree, self.gap_spacings * spacing)]
            if len(accepted):
                moved = moved[far_from(moved, cKDTree(accepted), self.fill_gap_spacings * spacing)]
            # the moved fill must still fit the rim: points off the rim's local plane are dropped
            # (what they covered is filled afresh below)
            moved = moved[~disagreeing(moved, rim, 3 * spacing, self.accept_spacings * spacing)]
            if len(moved):
                accepted = np.vstack([accepted, moved])

        # step 5b: what the frames with their own hole near R saw of it, where the hole is still open
        partial.sort(key=lambda c: (round(c[0] / spacing, 2), c[1], c[2]))
        seen = np.zeros((0, 3))
        for residual, _, _, points in partial:
            points = points[far_from(points, local_tree, self.gap_spacings * spacing)]
            known = np.vstack([accepted, seen])
            if len(known):
                points = points[far_from(points, cKDTree(known), self.fill_gap_spacings * spacing)]
            # step 4's agreement, widened by this copy's own misfit at the rim (its points near the rim sit
            # that far off the rim's surface however well the rest of it fits)
            points = points[grown_agreeing(points, np.vstack([rim, known]), 3 * spacing,
                                           self.accept_spacings * spacing + residual)]
            if len(points):
                seen = np.vstack([seen, points])

        # step 6: spatial fill, on the rim's surface, of what no frame saw (and nothing was reused)
        spatial = np.zeros((0, 3))
        if self.fallback and not full_copy:  # a copied frame saw all of R (step 3): its gaps are the capture's
            covered = cKDTree(np.vstack([local, accepted, seen])) if len(accepted) or len(seen) else local_tree
            support = np.vstack([rim, accepted[:copied]]) if copied else rim
            spatial = rim_surface_fill(support, region, covered, spacing, voxelized=ctx["voxelized"], step=ctx["step"],
                                       max_holdout_spacings=self.surface_holdout_spacings, ring=shell / 2,
                                       gap_spacings=self.fill_gap_spacings)
            sheet_fill = np.zeros((0, 3))
            if self.sheet and not len(spatial):
                # step 6f: step 6 on the hole's own sheet of the crop (a second surface in reach refused it);
                # what it leaves open goes on to steps 6c-6e
                sheet = rim_sheet(support, region, shell / 2, spacing)
                if sheet is not None:
                    sheet_fill = rim_surface_fill(sheet, region, covered, spacing, voxelized=ctx["voxelized"],
                                                  step=ctx["step"], max_holdout_spacings=self.surface_holdout_spacings,
                                                  ring=shell / 2, gap_spacings=self.fill_gap_spacings)
                    if len(sheet_fill):
                        covered = cKDTree(np.vstack([covered.data, sheet_fill]))
            capping = self.cap and ctx["voxelized"] and not len(spatial)
            cap_first = capping and self.walled_cap_first and cap_walled(local, region, spacing)
            if cap_first:
                # step 6d before 6c where walls rise from the opening: no surface round it continues over it
                spatial = self._cap(local, region, covered, spacing, ctx)
            in_box = self._keeps_captured(ctx["tree_of"](f), frames[f], region)
            poisson_fill = np.zeros((0, 3))
            if self.poisson and not len(spatial) and (self.poisson_in_boxes or not in_box):
                # step 6c: a hole the height field refused (round a limb, a neck), on the crop's closed surface
                spatial = poisson_surface_fill(np.vstack([local, accepted]), region, covered, spacing,
                                               voxelized=ctx["voxelized"], step=ctx["step"],
                                               gap_spacings=self.fill_gap_spacings, ring=shell / 2,
                                               max_holdout_spacings=self.surface_holdout_spacings,
                                               separate_bodies=self.poisson_bodies,
                                               bridge_ends=self.poisson_bridges)
                poisson_fill = spatial
            if capping and not cap_first and not len(spatial):
                # step 6d: an opening no surface round it continues (a base, a sole), spanned by a membrane
                spatial = self._cap(local, region, covered, spacing, ctx)
            after_poisson = (self.membrane_after_poisson and in_box and len(poisson_fill)
                             and len(spatial) == len(poisson_fill))
            if self.membrane and (not len(spatial) or after_poisson):
                # step 6e: a gap the membrane of the data round and inside it spans (an occlusion box's open parts)
                anchors = np.vstack([accepted, poisson_fill])
                gaps = cKDTree(np.vstack([covered.data, poisson_fill])) if len(poisson_fill) else covered
                membrane = membrane_fill(local, region, gaps, spacing, step=ctx["step"], accepted=anchors,
                                         partial=seen, gap_spacings=self.fill_gap_spacings,
                                         agree_spacings=self.accept_spacings,
                                         max_holdout_spacings=self.surface_holdout_spacings)
                ctx["not_reused"].append(membrane)
                spatial = np.vstack([spatial, membrane])
            if self.front and not len(spatial):
                # step 6b: what the one-surface fill refused, grown from the rim and copies chart by chart
                spatial = self._front(support, region, covered, rim, spacing, ctx["voxelized"], ctx["neighbours"])
            spatial = np.vstack([sheet_fill, spatial])
        if not len(accepted) and not len(spatial) and not len(seen):
            return np.zeros((0, 3))

        # step 7: copies and reused points onto the surface of rim + fused points
        # (on voxelized data the copies are voxels of a captured surface already: projecting them
        # onto a smooth fit and rounding back thins the staircase, measured -0.8 dB D1)
        first = copied if ctx["voxelized"] else 0
        if ctx["projection_neighbours"] >= 6 and first < len(accepted):
            support = np.vstack([local, accepted])
            accepted[first:] = mls_project(accepted[first:], support, ctx["projection_neighbours"])
        if ctx["voxelized"] and copied < len(accepted) and self.revoxelize:
            # step 4b's rule for the reused points too (moved by f-1's motion: sub-voxel positions)
            k = max(ctx["projection_neighbours"], 6)
            bound = rim_crossing_threshold(even_subset(rim, CALIBRATION_POINTS), region, local, local_tree, k)
            occupied = cKDTree(np.vstack([local, accepted[:copied]])) if copied else local_tree
            reused = surface_voxels(accepted[copied:], region, np.vstack([local, accepted]), occupied, k, bound)
            accepted = np.vstack([accepted[:copied], reused])
        elif ctx["voxelized"] and copied < len(accepted):
            accepted = np.vstack([accepted[:copied], unique_voxels(np.floor(accepted[copied:] + 0.5))])
        ctx["from_previous"].append(accepted[copied:])
        if len(seen):
            # step 5b's copies as step 7 treats the reused points: onto the surface, re-voxelized; not reused
            seen = self._settle(seen, accepted, region, local, rim, local_tree, ctx)
            ctx["not_reused"].append(seen)
        if len(accepted) or len(spatial):
            ctx["next_motion"] = None  # step 9 only where R stayed open but for step 5b's copies
        accepted = np.vstack([accepted, seen, spatial])
        return accepted[region.contains(accepted, margin=spacing)]

    def _settle(self, points, fixed, region, local, rim, local_tree, ctx) -> np.ndarray:
        """Step 7's treatment of moved points (``points`` (P, 3), beside the new points ``fixed`` of R): onto the MLS
        surface of frame f's crop ``local`` and all new points, then, on voxelized data, re-voxelized by step 4b's
        rule with the rim's bound, never on a voxel of ``local`` or ``fixed``."""
        support = np.vstack([local, fixed, points])
        if ctx["projection_neighbours"] >= 6:
            points = mls_project(points, support, ctx["projection_neighbours"])
        if ctx["voxelized"] and self.revoxelize:
            k = max(ctx["projection_neighbours"], 6)
            bound = rim_crossing_threshold(even_subset(rim, CALIBRATION_POINTS), region, local, local_tree, k)
            occupied = cKDTree(np.vstack([local, fixed])) if len(fixed) else local_tree
            points = surface_voxels(points, region, support, occupied, k, bound)
        elif ctx["voxelized"]:
            points = unique_voxels(np.floor(points + 0.5))
        return points

    def _cap(self, local, region, covered, spacing, ctx) -> np.ndarray:
        """Step 6d's membrane (`cap_fill`)."""
        spatial = cap_fill(local, region, covered, spacing, voxelized=ctx["voxelized"], step=ctx["step"],
                           gap_spacings=self.fill_gap_spacings, harmonic=self.harmonic_cap)
        if self.harmonic_cap:
            # frame f's own loop spans it afresh in each frame; moved on by each frame's motion it drifted
            ctx["not_reused"].append(spatial)
        return spatial

    def _front(self, support, region, covered, rim, spacing, voxelized, neighbours) -> np.ndarray:
        """Step 6b (`_front_fill.front_fill`): cell 1 voxel / s, `_rim_fill_rounds` rounds, residual bound
        the 90th percentile of the rim's own fit residual (`_front_fill.rim_residual_bound`)."""
        k = max(neighbours, 6)
        points = front_fill(support, region, covered, spacing, voxelized=voxelized, max_residual=rim_residual_bound(rim, k),
                            neighbours=k, max_rounds=self._rim_fill_rounds(k),
                            free_distance=spacing / 2 if voxelized else self.fill_gap_spacings * spacing)
        if voxelized and len(points):
            points = unique_voxels(np.floor(points + 0.5))
        return points

    def _fit_neighbours(self, voxelized: bool) -> int:
        """``mls_neighbours`` resolved: "auto" is `VOXEL_FIT_NEIGHBOURS` for the voxel decisions of steps 1b
        and 4b on voxelized input (``voxelized``), else `FIT_NEIGHBOURS` (step 7's projections, float input;
        the parameter list of the module docstring says why)."""
        if self.mls_neighbours == "auto":
            return VOXEL_FIT_NEIGHBOURS if voxelized else FIT_NEIGHBOURS
        return int(self.mls_neighbours)

    @staticmethod
    def _rim_fill_rounds(neighbours: int) -> int:
        """Rounds of step 1b: one fit radius, ceil(sqrt(k / pi)) spacings, the radius of the disc that
        the k = ``neighbours`` (at least 6) points a fit rests on cover at one point per s^2 (3 for k = 20
        and for k = 28): the rim's surface is extrapolated no farther than the data it is fitted to spans."""
        return max(1, int(np.ceil(np.sqrt(max(int(neighbours), 6) / np.pi))))

    def _deformed(self, points, field) -> np.ndarray:
        if field is None or len(field[0]) == 0 or len(points) == 0:
            return points
        anchors, displacement = field
        return points + interpolate_displacement(points, anchors, displacement, int(self.deform_neighbours))


__all__ = ["TemporalFusion", "PlaneTarget", "crossed_voxels", "crossing_offset", "disagreeing", "interpolate_displacement",
           "mls_fit", "mls_project", "plane_target", "refine_point_to_plane", "rim_crossing_threshold",
           "rim_displacement", "seen_rim_residual", "snap_to_voxels", "surface_voxels"]

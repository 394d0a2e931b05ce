set terminal pngcairo size 1000,900 noenhanced
set output 'tracking_equirect.png'
$errors << EOD
odvr, gt H.264	0	22.47
odvr, gt H.264	1	22.50
odvr, gt H.264	2	21.59
odvr, gt H.264	3	21.93
odvr, gt H.264	4	16.98
odvr, gt H.264	5	20.42
odvr, gt H.264	6	14.72
odvr, gt H.264	7	6.36
odvr, gt H.264	8	4.34
odvr, gt H.264	9	8.29
odvr, gt H.264	10	13.52
odvr, gt H.264	11	12.39
odvr, gt H.264	12	17.68
odvr, gt H.264	13	19.08
odvr, gt H.264	14	16.05
odvr, gt H.264	15	20.89
odvr, gt H.264	16	21.61
odvr, gt H.264	17	27.27
odvr, gt H.264	18	16.97
odvr, gt H.264	19	11.05
odvr, gt H.264	20	9.74
odvr, gt H.264	21	14.48
odvr, gt H.264	22	14.45
odvr, gt H.264	23	13.44
odvr, gt H.264	24	16.05
odvr, gt H.264	25	19.11
odvr, gt H.264	26	17.27
odvr, gt H.264	27	16.76
odvr, gt H.264	28	19.18
odvr, gt H.264	29	10.01
odvr, gt H.264	30	11.00
odvr, gt H.264	31	17.14
odvr, gt H.264	32	10.41
odvr, gt H.264	33	14.42
odvr, gt H.264	34	14.63
odvr, gt H.264	35	15.59
odvr, gt H.264	36	14.46
odvr, gt H.264	37	14.15
odvr, gt H.264	38	18.34
odvr, gt H.264	39	24.60
odvr, gt H.264, no height	0	22.47
odvr, gt H.264, no height	1	22.50
odvr, gt H.264, no height	2	21.59
odvr, gt H.264, no height	3	21.93
odvr, gt H.264, no height	4	16.98
odvr, gt H.264, no height	5	20.42
odvr, gt H.264, no height	6	14.72
odvr, gt H.264, no height	7	6.36
odvr, gt H.264, no height	8	4.34
odvr, gt H.264, no height	9	8.29
odvr, gt H.264, no height	10	13.52
odvr, gt H.264, no height	11	12.39
odvr, gt H.264, no height	12	17.68
odvr, gt H.264, no height	13	19.08
odvr, gt H.264, no height	14	16.05
odvr, gt H.264, no height	15	20.89
odvr, gt H.264, no height	16	21.61
odvr, gt H.264, no height	17	27.27
odvr, gt H.264, no height	18	16.97
odvr, gt H.264, no height	19	11.05
odvr, gt H.264, no height	20	9.74
odvr, gt H.264, no height	21	14.48
odvr, gt H.264, no height	22	14.45
odvr, gt H.264, no height	23	13.44
odvr, gt H.264, no height	24	16.05
odvr, gt H.264, no height	25	19.11
odvr, gt H.264, no height	26	17.27
odvr, gt H.264, no height	27	16.76
odvr, gt H.264, no height	28	19.18
odvr, gt H.264, no height	29	10.01
odvr, gt H.264, no height	30	11.00
odvr, gt H.264, no height	31	17.14
odvr, gt H.264, no height	32	10.41
odvr, gt H.264, no height	33	14.42
odvr, gt H.264, no height	34	14.63
odvr, gt H.264, no height	35	15.59
odvr, gt H.264, no height	36	14.46
odvr, gt H.264, no height	37	14.15
odvr, gt H.264, no height	38	18.34
odvr, gt H.264, no height	39	24.60
colmap faces, gt H.264	0	46.60
colmap faces, gt H.264	1	42.17
colmap faces, gt H.264	2	49.90
colmap faces, gt H.264	3	44.32
colmap faces, gt H.264	4	24.77
colmap faces, gt H.264	5	17.69
colmap faces, gt H.264	6	25.26
colmap faces, gt H.264	7	7.40
colmap faces, gt H.264	8	26.98
colmap faces, gt H.264	9	6.94
colmap faces, gt H.264	10	28.55
colmap faces, gt H.264	11	24.79
colmap faces, gt H.264	12	32.24
colmap faces, gt H.264	13	21.32
colmap faces, gt H.264	14	29.35
colmap faces, gt H.264	15	44.76
colmap faces, gt H.264	16	42.44
colmap faces, gt H.264	17	38.57
colmap faces, gt H.264	18	32.23
colmap faces, gt H.264	19	23.01
colmap faces, gt H.264	20	18.85
colmap faces, gt H.264	21	13.94
colmap faces, gt H.264	22	25.65
colmap faces, gt H.264	23	54.03
colmap faces, gt H.264	24	42.27
colmap faces, gt H.264	25	34.99
colmap faces, gt H.264	26	10.78
colmap faces, gt H.264	27	58.69
colmap faces, gt H.264	28	78.69
colmap faces, gt H.264	29	27.50
colmap faces, gt H.264	30	31.73
colmap faces, gt H.264	31	48.90
colmap faces, gt H.264	32	14.97
colmap faces, gt H.264	33	29.03
colmap faces, gt H.264	34	42.48
colmap faces, gt H.264	35	13.32
colmap faces, gt H.264	36	20.15
colmap faces, gt H.264	37	34.68
colmap faces, gt H.264	38	49.42
colmap faces, gt H.264	39	63.91
odvr, stitched H.264	0	39.29
odvr, stitched H.264	1	32.39
odvr, stitched H.264	2	22.40
odvr, stitched H.264	3	21.63
odvr, stitched H.264	4	13.03
odvr, stitched H.264	5	7.19
odvr, stitched H.264	6	11.58
odvr, stitched H.264	7	4.47
odvr, stitched H.264	8	25.02
odvr, stitched H.264	9	20.51
odvr, stitched H.264	10	29.19
odvr, stitched H.264	11	28.46
odvr, stitched H.264	12	26.16
odvr, stitched H.264	13	27.35
odvr, stitched H.264	14	22.36
odvr, stitched H.264	15	17.57
odvr, stitched H.264	16	12.34
odvr, stitched H.264	17	13.60
odvr, stitched H.264	18	17.11
odvr, stitched H.264	19	11.20
odvr, stitched H.264	20	10.57
odvr, stitched H.264	21	17.04
odvr, stitched H.264	22	24.03
odvr, stitched H.264	23	18.64
odvr, stitched H.264	24	20.69
odvr, stitched H.264	25	35.53
odvr, stitched H.264	26	38.14
odvr, stitched H.264	27	36.29
odvr, stitched H.264	28	28.64
odvr, stitched H.264	29	22.40
odvr, stitched H.264	30	18.83
odvr, stitched H.264	31	23.24
odvr, stitched H.264	32	16.53
odvr, stitched H.264	33	12.07
odvr, stitched H.264	34	7.06
odvr, stitched H.264	35	13.05
odvr, stitched H.264	36	18.28
odvr, stitched H.264	37	16.49
odvr, stitched H.264	38	31.02
odvr, stitched H.264	39	39.91
odvr, stitched H.264, no height	0	39.29
odvr, stitched H.264, no height	1	32.39
odvr, stitched H.264, no height	2	22.40
odvr, stitched H.264, no height	3	21.63
odvr, stitched H.264, no height	4	13.03
odvr, stitched H.264, no height	5	7.19
odvr, stitched H.264, no height	6	11.58
odvr, stitched H.264, no height	7	4.47
odvr, stitched H.264, no height	8	25.02
odvr, stitched H.264, no height	9	20.51
odvr, stitched H.264, no height	10	29.19
odvr, stitched H.264, no height	11	28.46
odvr, stitched H.264, no height	12	26.16
odvr, stitched H.264, no height	13	27.35
odvr, stitched H.264, no height	14	22.36
odvr, stitched H.264, no height	15	17.57
odvr, stitched H.264, no height	16	12.34
odvr, stitched H.264, no height	17	13.60
odvr, stitched H.264, no height	18	17.11
odvr, stitched H.264, no height	19	11.20
odvr, stitched H.264, no height	20	10.57
odvr, stitched H.264, no height	21	17.04
odvr, stitched H.264, no height	22	24.03
odvr, stitched H.264, no height	23	18.64
odvr, stitched H.264, no height	24	20.69
odvr, stitched H.264, no height	25	35.53
odvr, stitched H.264, no height	26	38.14
odvr, stitched H.264, no height	27	36.29
odvr, stitched H.264, no height	28	28.64
odvr, stitched H.264, no height	29	22.40
odvr, stitched H.264, no height	30	18.83
odvr, stitched H.264, no height	31	23.24
odvr, stitched H.264, no height	32	16.53
odvr, stitched H.264, no height	33	12.07
odvr, stitched H.264, no height	34	7.06
odvr, stitched H.264, no height	35	13.05
odvr, stitched H.264, no height	36	18.28
odvr, stitched H.264, no height	37	16.49
odvr, stitched H.264, no height	38	31.02
odvr, stitched H.264, no height	39	39.91
colmap faces, stitched H.264	0	132.63
colmap faces, stitched H.264	1	76.82
colmap faces, stitched H.264	2	54.32
colmap faces, stitched H.264	3	23.76
colmap faces, stitched H.264	4	10.46
colmap faces, stitched H.264	5	22.17
colmap faces, stitched H.264	6	15.92
colmap faces, stitched H.264	7	26.64
colmap faces, stitched H.264	8	29.60
colmap faces, stitched H.264	9	23.42
colmap faces, stitched H.264	10	14.51
colmap faces, stitched H.264	11	31.04
colmap faces, stitched H.264	12	51.47
colmap faces, stitched H.264	13	64.40
colmap faces, stitched H.264	14	60.47
colmap faces, stitched H.264	15	40.11
colmap faces, stitched H.264	16	30.40
colmap faces, stitched H.264	17	37.75
colmap faces, stitched H.264	18	30.10
colmap faces, stitched H.264	19	21.01
colmap faces, stitched H.264	20	26.54
colmap faces, stitched H.264	21	28.02
colmap faces, stitched H.264	22	21.27
colmap faces, stitched H.264	23	21.28
colmap faces, stitched H.264	24	42.26
colmap faces, stitched H.264	25	49.42
colmap faces, stitched H.264	26	36.72
colmap faces, stitched H.264	27	5.98
colmap faces, stitched H.264	28	5.58
colmap faces, stitched H.264	29	11.82
colmap faces, stitched H.264	30	7.21
colmap faces, stitched H.264	31	5.34
colmap faces, stitched H.264	32	7.51
colmap faces, stitched H.264	33	11.21
colmap faces, stitched H.264	34	37.20
colmap faces, stitched H.264	35	17.29
colmap faces, stitched H.264	36	24.87
colmap faces, stitched H.264	37	15.75
colmap faces, stitched H.264	38	26.79
colmap faces, stitched H.264	39	28.89
odvr, stitched H.264 tracked at 2048	0	35.75
odvr, stitched H.264 tracked at 2048	1	31.77
odvr, stitched H.264 tracked at 2048	2	25.22
odvr, stitched H.264 tracked at 2048	3	20.62
odvr, stitched H.264 tracked at 2048	4	18.68
odvr, stitched H.264 tracked at 2048	5	20.49
odvr, stitched H.264 tracked at 2048	6	14.82
odvr, stitched H.264 tracked at 2048	7	8.98
odvr, stitched H.264 tracked at 2048	8	3.11
odvr, stitched H.264 tracked at 2048	9	4.94
odvr, stitched H.264 tracked at 2048	10	14.90
odvr, stitched H.264 tracked at 2048	11	18.02
odvr, stitched H.264 tracked at 2048	12	4.33
odvr, stitched H.264 tracked at 2048	13	22.80
odvr, stitched H.264 tracked at 2048	14	20.91
odvr, stitched H.264 tracked at 2048	15	19.92
odvr, stitched H.264 tracked at 2048	16	24.51
odvr, stitched H.264 tracked at 2048	17	30.83
odvr, stitched H.264 tracked at 2048	18	32.48
odvr, stitched H.264 tracked at 2048	19	28.28
odvr, stitched H.264 tracked at 2048	20	23.33
odvr, stitched H.264 tracked at 2048	21	16.89
odvr, stitched H.264 tracked at 2048	22	11.35
odvr, stitched H.264 tracked at 2048	23	8.24
odvr, stitched H.264 tracked at 2048	24	13.70
odvr, stitched H.264 tracked at 2048	25	9.45
odvr, stitched H.264 tracked at 2048	26	14.06
odvr, stitched H.264 tracked at 2048	27	6.73
odvr, stitched H.264 tracked at 2048	28	6.63
odvr, stitched H.264 tracked at 2048	29	5.00
odvr, stitched H.264 tracked at 2048	30	6.28
odvr, stitched H.264 tracked at 2048	31	7.83
odvr, stitched H.264 tracked at 2048	32	2.27
odvr, stitched H.264 tracked at 2048	33	4.96
odvr, stitched H.264 tracked at 2048	34	22.01
odvr, stitched H.264 tracked at 2048	35	27.62
odvr, stitched H.264 tracked at 2048	36	37.09
odvr, stitched H.264 tracked at 2048	37	13.98
odvr, stitched H.264 tracked at 2048	38	43.10
odvr, stitched H.264 tracked at 2048	39	12.92
odvr rig	0	9.11
odvr rig	1	8.02
odvr rig	2	7.53
odvr rig	3	7.06
odvr rig	4	6.54
odvr rig	5	4.49
odvr rig	6	3.54
odvr rig	7	3.86
odvr rig	8	2.72
odvr rig	9	4.10
odvr rig	10	2.49
odvr rig	11	4.88
odvr rig	12	3.98
odvr rig	13	5.65
odvr rig	14	6.38
odvr rig	15	5.85
odvr rig	16	6.92
odvr rig	17	5.15
odvr rig	18	5.55
odvr rig	19	7.25
odvr rig	20	8.12
odvr rig	21	5.68
odvr rig	22	8.99
odvr rig	23	8.49
odvr rig	24	8.96
odvr rig	25	5.82
odvr rig	26	1.79
odvr rig	27	3.87
odvr rig	28	6.94
odvr rig	29	1.37
odvr rig	30	2.62
odvr rig	31	3.75
odvr rig	32	3.53
odvr rig	33	3.86
odvr rig	34	3.94
odvr rig	35	6.63
odvr rig	36	7.59
odvr rig	37	7.31
odvr rig	38	7.02
odvr rig	39	7.92
EOD
set datafile separator '\t'
set multiplot layout 2,1
set key outside right
set grid
set size ratio -1
set title 'trajectory seen from above (ground-truth world, estimates similarity-aligned)'
set xlabel 'x (m)'
set ylabel 'y (m)'
plot 'tracking_equirect_paths.tsv' using (strcol(1) eq 'ground truth' ? $3 : 1/0):4 with lines lw 5 lc rgb '#aaaaaa' title 'ground truth', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, gt H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 1 title 'odvr, gt H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, gt H.264, no height' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 2 title 'odvr, gt H.264, no height', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'colmap faces, gt H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 3 title 'colmap faces, gt H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 4 title 'odvr, stitched H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264, no height' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 5 title 'odvr, stitched H.264, no height', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'colmap faces, stitched H.264' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 6 title 'colmap faces, stitched H.264', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr, stitched H.264 tracked at 2048' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 7 title 'odvr, stitched H.264 tracked at 2048', 'tracking_equirect_paths.tsv' using (strcol(1) eq 'odvr rig' ? $3 : 1/0):4 with linespoints pt 7 ps 0.5 lc 8 title 'odvr rig'
set size noratio
set title 'position error after the alignment'
set xlabel 'frame'
set ylabel 'mm'
set logscale y
plot $errors using (strcol(1) eq 'odvr, gt H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 1 title 'odvr, gt H.264', $errors using (strcol(1) eq 'odvr, gt H.264, no height' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 2 title 'odvr, gt H.264, no height', $errors using (strcol(1) eq 'colmap faces, gt H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 3 title 'colmap faces, gt H.264', $errors using (strcol(1) eq 'odvr, stitched H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 4 title 'odvr, stitched H.264', $errors using (strcol(1) eq 'odvr, stitched H.264, no height' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 5 title 'odvr, stitched H.264, no height', $errors using (strcol(1) eq 'colmap faces, stitched H.264' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 6 title 'colmap faces, stitched H.264', $errors using (strcol(1) eq 'odvr, stitched H.264 tracked at 2048' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 7 title 'odvr, stitched H.264 tracked at 2048', $errors using (strcol(1) eq 'odvr rig' ? $2 : 1/0):($3 > 0.01 ? $3 : 0.01) with linespoints pt 7 ps 0.5 lc 8 title 'odvr rig'
unset multiplot

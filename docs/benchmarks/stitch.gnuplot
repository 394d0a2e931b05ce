set terminal pngcairo size 900,520 noenhanced
set output 'stitch.png'
set datafile separator '\t'
set logscale x
set key outside right
set grid
set title 'stitching 1024x512: PSNR against the ground truth vs time per frame'
set xlabel 'ms per frame'
set ylabel 'PSNR (dB)'
plot 'stitch.tsv' using (strcol(2) eq 'odvr cpu' ? $3 : 1/0):4 with points pt 7 ps 1.5 lc 1 title 'odvr cpu (valid)', 'stitch.tsv' using (strcol(2) eq 'odvr cpu' ? $3 : 1/0):5 with points pt 6 ps 1.5 lc 1 title 'odvr cpu (seams)', 'stitch.tsv' using (strcol(2) eq 'odvr gpu' ? $3 : 1/0):4 with points pt 7 ps 1.5 lc 2 title 'odvr gpu (valid)', 'stitch.tsv' using (strcol(2) eq 'odvr gpu' ? $3 : 1/0):5 with points pt 6 ps 1.5 lc 2 title 'odvr gpu (seams)', 'stitch.tsv' using (strcol(2) eq 'opencv' ? $3 : 1/0):4 with points pt 7 ps 1.5 lc 3 title 'opencv (valid)', 'stitch.tsv' using (strcol(2) eq 'opencv' ? $3 : 1/0):5 with points pt 6 ps 1.5 lc 3 title 'opencv (seams)'

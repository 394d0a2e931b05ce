set terminal pngcairo size 1200,520 noenhanced
set output 'lighting.png'
set datafile separator '\t'
set logscale xy
set key outside bottom center horizontal
set grid
set multiplot layout 1,2
set title 'diffuse error against time (all maps, widths)'
set xlabel 'ms'
set ylabel 'diffuse error'
plot 'lighting.tsv' using (strcol(3) eq 'sg' && strcol(4) eq 'cpu' ? $7 : 1/0):9 with points title 'sg', 'lighting.tsv' using (strcol(3) eq 'sg' && strcol(4) eq 'gpu' ? $7 : 1/0):9 with points title 'sg (gpu)', 'lighting.tsv' using (strcol(3) eq 'sg+peaks' && strcol(4) eq 'cpu' ? $7 : 1/0):9 with points title 'sg+peaks', 'lighting.tsv' using (strcol(3) eq 'sg+peaks' && strcol(4) eq 'gpu' ? $7 : 1/0):9 with points title 'sg+peaks (gpu)', 'lighting.tsv' using (strcol(3) eq 'least-squares' && strcol(4) eq 'cpu' ? $7 : 1/0):9 with points title 'least-squares', 'lighting.tsv' using (strcol(3) eq 'least-squares+peaks' && strcol(4) eq 'cpu' ? $7 : 1/0):9 with points title 'least-squares+peaks', 'lighting.tsv' using (strcol(3) eq 'sh' && strcol(4) eq 'cpu' ? $7 : 1/0):9 with points title 'sh'
set title 'glossy200 error against time (all maps, widths)'
set xlabel 'ms'
set ylabel 'glossy200 error'
plot 'lighting.tsv' using (strcol(3) eq 'sg' && strcol(4) eq 'cpu' ? $7 : 1/0):11 with points title 'sg', 'lighting.tsv' using (strcol(3) eq 'sg' && strcol(4) eq 'gpu' ? $7 : 1/0):11 with points title 'sg (gpu)', 'lighting.tsv' using (strcol(3) eq 'sg+peaks' && strcol(4) eq 'cpu' ? $7 : 1/0):11 with points title 'sg+peaks', 'lighting.tsv' using (strcol(3) eq 'sg+peaks' && strcol(4) eq 'gpu' ? $7 : 1/0):11 with points title 'sg+peaks (gpu)', 'lighting.tsv' using (strcol(3) eq 'least-squares' && strcol(4) eq 'cpu' ? $7 : 1/0):11 with points title 'least-squares', 'lighting.tsv' using (strcol(3) eq 'least-squares+peaks' && strcol(4) eq 'cpu' ? $7 : 1/0):11 with points title 'least-squares+peaks', 'lighting.tsv' using (strcol(3) eq 'sh' && strcol(4) eq 'cpu' ? $7 : 1/0):11 with points title 'sh'
unset multiplot

set terminal pngcairo size 900,480 noenhanced
set output 'decode.png'
set datafile separator '\t'
set datafile columnheaders
set style data histogram
set style histogram cluster gap 1
set style fill solid 0.8 border -1
set ylabel 'ms per frame (median)'
set xtics rotate by -20
set key top left
set grid ytics
plot 'decode.tsv' using 4:xtic(1) title 'libav', '' using 7 title 'OpenCV VideoCapture'
